/* abbe: the extras of the single-precision evaluation (backlash, thermal, format
 * 1.1's reversal blocks) and the refusal test of their inputs: the functions that
 * eval_f32_linear.h (the 3-axis and five-axis evaluations) and eval_f32_x86.h call
 * through internal.h's declarations. Their home depends on headers only and calls
 * nothing back; eval_f32.c includes it, so its translation unit is what it was
 * before the split (same object code, bench/results.md unchanged), and their
 * definitions stay external ones, compiled once: the x86-64 cores (eval_f32_sse2.c,
 * eval_f32_avx2.c) and the five-axis evaluation link to them. Include it from
 * eval_f32.c only (a second translation unit would define them twice). Not installed. */
#ifndef ABBE_EVAL_F32_EXTRAS_H
#define ABBE_EVAL_F32_EXTRAS_H

#include "internal.h"

#define BACKLASH_UM_PER_LSB 3.90625e-6f                 /* 2^-8 nm in um */
#define EXPANSION_PER_K_PER_LSB 8.8817841970012523e-13f /* 2^-50 per mK, per K */
#define OFFSET_UM_PER_K_PER_LSB 1.52587890625e-5f       /* 2^-16 nm per mK = um per K */

#if !defined(ABBE_NO_REVERSAL)
/* An axis' reversal block (format 1.1) at its offset d: sum_k r_k T_k(u) in
 * 2^-8 nm, u the trend's argument (the clamped position), the rows by the
 * trend's recurrence. The axis must have a block (reversal_rows > 0). */
static ABBE_ALWAYS_INLINE float reversal_block_f32(const abbe_axis_model_t *ax, uint32_t d)
{
    const uint8_t *row = ax->coef_f32 + 4u * ((unsigned)ax->n_basis * ax->n_terms);
    const float u = (float)abbe_arg_cheb_q30(ax, d) * 9.31322574615478515625e-10f; /* 2^-30 */
    const float two_u = u + u;
    float t_prev = 1.0f, t = u;
    float r = abbe_ld_f32_aligned(row);
    /*@ loop unroll ABBE_MAX_REVERSAL_ROWS; */
    for (unsigned k = 1; k < ax->reversal_rows; k++) {
        r += abbe_ld_f32_aligned(row + 4u * k) * t;
        float t_next = two_u * t - t_prev; /* T_k = 2u T_(k-1) - T_(k-2) */
        t_prev = t;
        t = t_next;
    }
    return r;
}

/* s R(p) / 2 on the own positioning term of each axis with a reversal block,
 * beside the backlash's s B / 2. Out of line and called last by
 * abbe_f32_add_extras, so a table without blocks runs that function's code as
 * a 1.0 table did (plus one feature test). */
ABBE_NOINLINE static void add_reversal_blocks(const abbe_model_t *m, const uint32_t d[ABBE_AXES],
                                              const float dir_state[ABBE_AXES], float error_um[ABBE_AXES])
{
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        const abbe_axis_model_t *ax = &m->axis[j];
        if (ax->reversal_rows == 0u) {
            continue;
        }
        float s = dir_state[j] > 1.0f ? 1.0f : (dir_state[j] < -1.0f ? -1.0f : dir_state[j]);
        float um = 0.5f * s * (reversal_block_f32(ax, d[j]) * BACKLASH_UM_PER_LSB);
        error_um[j] += j == 2u ? um : -um;
    }
}
#endif

void abbe_f32_add_extras(const abbe_model_t *m, const float lev_mm[ABBE_AXES],
#if !defined(ABBE_NO_REVERSAL)
                         const uint32_t d[ABBE_AXES],
#endif
                         const float dir_state[ABBE_AXES], const float temp_c[ABBE_AXES], float error_um[ABBE_AXES])
{
    /* Backlash and thermal terms of each axis' own positioning error, um;
     * lev_mm = p - ref. They add to -d_x(x) in dX, -d_y(y) in dY, +d_z(z) in dZ. */
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        const abbe_axis_model_t *ax = &m->axis[j];
        float um = 0.0f;
        if (m->features & ABBE_FEATURE_BACKLASH) {
            float s = dir_state[j] > 1.0f ? 1.0f : (dir_state[j] < -1.0f ? -1.0f : dir_state[j]);
            um += 0.5f * s * ((float)ax->backlash_reversal_q8 * BACKLASH_UM_PER_LSB);
        }
        if (m->features & ABBE_FEATURE_THERMAL) {
            float dt = temp_c[j] - (float)ax->thermal_tref_mdegc * 1.0e-3f;
            float strain = (float)ax->thermal_expansion_q50 * EXPANSION_PER_K_PER_LSB * dt;
            um += strain * lev_mm[j] * 1000.0f;
            um += (float)ax->thermal_offset_q16 * OFFSET_UM_PER_K_PER_LSB * dt;
        }
        error_um[j] += j == 2u ? um : -um;
    }
#if !defined(ABBE_NO_REVERSAL)
    if (m->features & ABBE_FEATURE_REVERSAL) {
        add_reversal_blocks(m, d, dir_state, error_um);
    }
#endif
}

int abbe_f32_extras_nonfinite(uint32_t features, const float dir_state[ABBE_AXES], const float temp_c[ABBE_AXES])
{
    int bad = 0;
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        bad |= ((features & ABBE_FEATURE_BACKLASH) && abbe_f32_nonfinite(dir_state[j])) ||
               ((features & ABBE_FEATURE_THERMAL) && abbe_f32_temp_invalid(temp_c[j]));
    }
    return bad;
}

#endif /* ABBE_EVAL_F32_EXTRAS_H */
