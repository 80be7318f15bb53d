/* abbe: spatial error, single precision (Eq. 3 + Abbe terms + extras).
 *
 * Positions are converted to integer nm first (exact to 0.56 nm), so clamping,
 * the Chebyshev argument and the Fourier phases are those of the fixed-point
 * path. Term values come in the coefficients' units (2^-8 nm, 2^-36 rad); the
 * lever arms are scaled once so that lever x angle is in um, and each axis'
 * six values are folded into (dX, dY, dZ) as soon as they are known, each by
 * one multiply-add: no term array, no per-term scaling.
 */
#include "eval_f32_linear.h"

#if !ABBE_WITH_F32
#error "this is the _f32 variant: compile it with ABBE_WITH_F32=1 (or leave it undefined), or leave the file out"
#endif

#define UM_PER_LIN_LSB ABBE_UM_PER_LIN_LSB
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
               ((features & ABBE_FEATURE_THERMAL) && abbe_f32_nonfinite(temp_c[j]));
    }
    return bad;
}

#if !defined(ABBE_F32_SSE2) /* x86-64: eval_f32_sse2.c */
abbe_status_t abbe_eval_f32_core(const abbe_model_t *m, const abbe_input_f32_t *in, abbe_error_f32_t *out)
{
    const uint32_t flags = eval_f32_linear(m, in->pos_mm, in->dir_state, in->temp_c, out->error_um, NULL, NULL);
    if (flags == ABBE_FLAG_INPUT_INVALID) { /* never set by the evaluation itself */
        out->flags = 0;
        return ABBE_E_INPUT;
    }
    out->flags = flags;
    return ABBE_OK;
}
#endif /* !ABBE_F32_SSE2 */

void abbe_f32_refuse(abbe_error_f32_t *out)
{
    out->error_um[0] = out->error_um[1] = out->error_um[2] = 0.0f;
    out->flags = 0;
}

abbe_status_t abbe_error_eval_f32(const abbe_model_t *m, const abbe_input_f32_t *in, abbe_error_f32_t *out)
{
    if (m == NULL || in == NULL || out == NULL) {
        return ABBE_E_ARG;
    }
    return abbe_eval_f32_core(m, in, out);
}

abbe_status_t abbe_error_eval_batch_f32(const abbe_model_t *m, size_t n, const abbe_input_f32_t *in,
                                        abbe_error_f32_t *out)
{
    if (m == NULL || (n > 0u && (in == NULL || out == NULL))) {
        return ABBE_E_ARG;
    }
    abbe_status_t result = ABBE_OK;
    for (size_t i = 0; i < n; i++) {
        if (abbe_eval_f32_core(m, &in[i], &out[i]) != ABBE_OK) {
            out[i].flags = ABBE_FLAG_INPUT_INVALID;
            result = ABBE_E_INPUT;
        }
    }
    return result;
}

abbe_status_t abbe_term_eval_f32(const abbe_model_t *m, unsigned axis, unsigned term, float pos_mm,
                                 float *value)
{
    if (m == NULL || value == NULL || axis >= ABBE_AXES || term >= ABBE_TERMS) {
        return ABBE_E_ARG;
    }
    uint32_t flags = 0;
    int32_t pos_nm;
    if (abbe_mm_to_nm_f32(pos_mm, &pos_nm, &flags) != ABBE_OK) {
        return ABBE_E_INPUT;
    }
    const abbe_axis_model_t *ax = &m->axis[axis];
    float v[ABBE_TERMS];
    abbe_axis_terms_f32(ax, abbe_arg_offset(ax, pos_nm, &flags), v);
    *value = v[term] * (term < 3u ? UM_PER_LIN_LSB : 1.4551915228366852e-5f); /* 2^-36 rad in urad */
    return ABBE_OK;
}

abbe_status_t abbe_reversal_eval_f32(const abbe_model_t *m, unsigned axis, float pos_mm, float *value_um)
{
    if (m == NULL || value_um == NULL || axis >= ABBE_AXES) {
        return ABBE_E_ARG;
    }
    uint32_t flags = 0;
    int32_t pos_nm;
    if (abbe_mm_to_nm_f32(pos_mm, &pos_nm, &flags) != ABBE_OK) {
        return ABBE_E_INPUT;
    }
    const abbe_axis_model_t *ax = &m->axis[axis];
    float r = (float)ax->backlash_reversal_q8;
#if !defined(ABBE_NO_REVERSAL)
    if (ax->reversal_rows != 0u) {
        r += reversal_block_f32(ax, abbe_arg_offset(ax, pos_nm, &flags));
    }
#endif
    *value_um = r * BACKLASH_UM_PER_LSB;
    return ABBE_OK;
}
