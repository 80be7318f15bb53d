/* abbe: the in-place model view of a validated table (abbe_model_t): the
 * axes' constants the evaluation needs (Chebyshev scaling, Fourier
 * frequencies and phases, take-up rates) and the position-independent
 * constants of Eq. 3, computed once at load so a cycle does not. Runs only
 * on a table every check of model_load_checks.h passed. Part of
 * model_load.c (see model_load_layout.h for why a header of static
 * functions). Not installed. */
#ifndef ABBE_MODEL_LOAD_VIEW_H
#define ABBE_MODEL_LOAD_VIEW_H

#include "model_load_layout.h"

/* round(2^64 / d) for 0 < d < 2^31, without a 128-bit type. */
ABBE_NOINLINE static uint64_t recip64(uint32_t d)
{
    uint64_t q = UINT64_MAX / d;
    uint64_t r = UINT64_MAX % d + 1u; /* 2^64 = q*d + r, 1 <= r <= d */
    if (r == d) {
        return q + 1u;
    }
    return q + (2u * r >= d ? 1u : 0u);
}

/* *ax as the view of the axis record rec of table b. Every field is stored
 * here, the conditional ones (the coefficient pointers, the take-up rate,
 * the reversal rows without format 1.1) zero in their other branch; the
 * padding is zero from build_model's memset of the whole model, build_axis'
 * one caller. No memset of *ax here: its char-pointer view is a cast WP's
 * Typed memory model cannot follow, and build_axis' contract (layout_ok,
 * model_load_acsl.h) is WP-proven (docs/proofs.md, "WP: loader
 * contracts"). */
static void build_axis(abbe_axis_model_t *ax, const uint8_t *b, const uint8_t *rec)
{
    ax->travel_min_nm = abbe_ld_i32(rec + A_MIN);
    ax->travel_max_nm = abbe_ld_i32(rec + A_MAX);
    ax->term_mask = rec[A_MASK];
    ax->n_terms = (uint8_t)popcount6(ax->term_mask);
    ax->trend_rows = (uint8_t)trend_rows_of(rec[A_DEGREE]);
    ax->n_basis = (uint8_t)n_basis_of(rec);
    uint8_t column = 0;
    /*@ WP_LOOP_COLUMNS */
    for (unsigned t = 0; t < ABBE_TERMS; t++) {
        if (((unsigned)ax->term_mask >> t) & 1u) {
            ax->column[t] = column++;
        } else {
            ax->column[t] = 0xFFu;
        }
    }
    if (abbe_ld_u32(rec + A_COEF_COUNT) != 0u) {
        ax->coef_q = b + abbe_ld_u32(rec + A_COEF_Q);
        ax->coef_f32 = b + abbe_ld_u32(rec + A_COEF_F32);
    } else {
        ax->coef_q = NULL;
        ax->coef_f32 = NULL;
    }
    /* Chebyshev argument (abbe_arg_cheb_q30): with n the bit length of the
     * span, shift = 32 - n keeps d << shift below 2^32, and
     * cheb_mul = round(2^(31 + n) / span) lies in (2^31, 2^32], 2^32 only for
     * a power-of-two span, stored as 2^32 - 1 (exact all the same there:
     * d << shift <= 2^31, internal.h). */
    uint32_t span = (uint32_t)ax->travel_max_nm - (uint32_t)ax->travel_min_nm; /* < 2^32, > 0 */
    span = span != 0u ? span : 1u; /* never binds (check_travel): the divisor's bound, stated for the proof */
    unsigned n = bit_length(span);
    uint64_t mul = (((uint64_t)1 << (31u + n)) + span / 2u) / span;
    ax->span_nm = span;
    ax->cheb_shift = (uint8_t)(32u - n);
    ax->cheb_mul = mul > UINT32_MAX ? UINT32_MAX : (uint32_t)mul;
    /* the two blocks' harmonics (ABBE_BLOCKS is 2), stored before their
     * loop so that it writes no count (WP: the loop's assigns leave every
     * uint8_t field as it is) */
    ax->harmonics[0] = rec[A_HARMONICS];
    ax->harmonics[1] = rec[A_HARMONICS + 1u];
    /*@ WP_LOOP_BLOCKS */
    for (unsigned k = 0; k < ABBE_BLOCKS; k++) {
        int32_t origin = abbe_ld_i32(rec + A_ORIGIN + 4u * k);
        int32_t period = abbe_ld_i32(rec + A_PERIOD + 4u * k);
        ax->freq[k] = period > 0 ? recip64((uint32_t)period) : 0u;
        /* phase of travel_min, so an evaluation multiplies only d = p - min */
        uint64_t from_origin = (uint64_t)((int64_t)ax->travel_min_nm - origin); /* mod 2^64 */
        ax->phase_min[k] = from_origin * ax->freq[k];
    }
    ax->backlash_reversal_q8 = abbe_ld_i32(rec + A_BACKLASH);
    const int32_t takeup_nm = abbe_ld_i32(rec + A_TAKEUP); /* a local: the divisor's test is where it is read */
    ax->backlash_takeup_nm = takeup_nm;
    if (takeup_nm > 0) {
        uint64_t takeup = (uint64_t)takeup_nm;
        ax->takeup_rate_q46 = (((uint64_t)1 << 46) + takeup / 2u) / takeup;
    } else {
        ax->takeup_rate_q46 = 0u;
    }
    ax->thermal_expansion_q50 = abbe_ld_i32(rec + A_EXPANSION);
    ax->thermal_offset_q16 = abbe_ld_i32(rec + A_THERMAL_OFFSET);
    ax->thermal_tref_mdegc = abbe_ld_i32(rec + A_TREF);
#if !defined(ABBE_NO_REVERSAL)
    ax->reversal_rows = rec[A_REVERSAL_ROWS];
#else
    ax->reversal_rows = 0u;
#endif
}

/* The constants of Eq. 3 that do not depend on the position (abbe_eval_*_core). */
static void build_assembly(abbe_model_t *m)
{
    const int64_t sxy = m->squareness_q36[0], sxz = m->squareness_q36[1], syz = m->squareness_q36[2];
    for (unsigned k = 0; k < ABBE_AXES; k++) {
        const abbe_axis_model_t *ax = &m->axis[k];
        m->ref_half_nm[k] = m->reference_nm[k] >> 1;
        m->any_block1 |= (uint8_t)(ax->harmonics[1] != 0u);
#if defined(ABBE_X86_LANES)
        m->lane_min_nm[k] = ax->travel_min_nm;
        m->lane_max_nm[k] = ax->travel_max_nm;
        m->lane_span_nm[k] = ax->span_nm;
        m->lane_cheb_shift[k] = ax->cheb_shift;
        m->lane_cheb_mul[k] = ax->cheb_mul;
#if defined(ABBE_MODEL_X86_64_LANES)
        for (unsigned b = 0; b < ABBE_BLOCKS; b++) {
            m->lane_freq[b][k] = ax->freq[b];
            m->lane_phase_min[b][k] = ax->phase_min[b];
        }
#endif
#endif
#if ABBE_WITH_F32
        /* converted in the FPU (rounded to nearest even, the rounding of
         * i32_to_f32_bits); t / 2 is exact (|t| >= 1 is far from the
         * subnormals). Not through the bits: the proof (docs/proofs.md) sees
         * a converted integer is finite, not that a bit pattern is. */
        m->tool_half_nm[k] = (float)m->tool_offset_nm[k] * 0.5f;
        m->squareness_f[k] = (float)m->squareness_q36[k];
#endif
    }
#if defined(ABBE_X86_LANES)
    /* negated before the conversion (sign-symmetric, so exact); |S| <= 2^28 */
    m->square_dx_dy[0] = m->squareness_f[0];
    m->square_dx_dy[1] = (float)-m->squareness_q36[2];
    m->square_dx_f[0] = (float)-m->squareness_q36[1];
#endif
    /* dX has y S_xy - z S_xz, dY has -z S_yz, with y = p_y - ref_y, z = p_z - ref_z:
     * the ref parts are constants (|ref * S| <= 2^59). */
    m->square_const_q36[0] = -(int64_t)m->reference_nm[1] * sxy + (int64_t)m->reference_nm[2] * sxz;
    m->square_const_q36[1] = (int64_t)m->reference_nm[2] * syz;
}

/* A field as the model keeps it: v within +/-cap, the cap its check
 * refused beyond (check_ranges: SQUARENESS_CAP; check_rotary: also
 * GEOMETRY_CAP). A no-op on every accepted table; done where the value is
 * stored so that the proof of the evaluation for any accepted table
 * (docs/proofs.md) sees the bound its products rely on (an interval analysis
 * does not connect the check's read of the field to this one). Load time
 * only. */
ABBE_NOINLINE static int32_t capped_i32(int32_t v, int32_t cap)
{
    return v > cap ? cap : (v < -cap ? -cap : v);
}

/* *model as a view of the validated table b. */
static ABBE_ALWAYS_INLINE void build_model(abbe_model_t *model, const uint8_t *b, uint32_t total)
{
    memset(model, 0, sizeof *model);
    model->blob = b;
    model->size = total;
    model->crc = abbe_ld_u32(b + total - 4u);
    model->features = abbe_ld_u32(b + H_FEATURES);
    model->version_major = abbe_ld_u16(b + H_MAJOR);
    model->version_minor = abbe_ld_u16(b + H_MINOR);
    for (unsigned k = 0; k < 3u; k++) {
        model->reference_nm[k] = abbe_ld_i32(b + H_REFERENCE + 4u * k);
        model->tool_offset_nm[k] = abbe_ld_i32(b + H_TOOL + 4u * k);
        model->squareness_q36[k] = capped_i32(abbe_ld_i32(b + H_SQUARENESS + 4u * k), SQUARENESS_CAP);
    }
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        build_axis(&model->axis[j], b, b + HEADER_SIZE + j * AXIS_RECORD_SIZE);
    }
    build_assembly(model);
#if defined(ABBE_X86_V3)
    model->simd = abbe_simd_level();
#endif
}

#endif /* ABBE_MODEL_LOAD_VIEW_H */
