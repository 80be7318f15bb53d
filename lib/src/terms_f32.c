/* abbe: fitted term values of one axis, single precision.
 *
 * Same structure as terms_q.c; the argument reduction stays integer, the basis
 * and the dot products are float. The float32 coefficients are the int32
 * coefficients converted (same units: 2^-8 nm, 2^-36 rad), so each term is
 * scaled to um or urad once at the end.
 */
#include "internal.h"

#define UM_PER_LIN_LSB 3.90625e-6f              /* 2^-8 nm */
#define URAD_PER_ANG_LSB 1.4551915228366852e-5f /* 2^-36 rad */

static ABBE_ALWAYS_INLINE const uint8_t *mac_row_f32(const uint8_t *row, float b, unsigned n_terms,
                                                      float *restrict acc)
{
    if (n_terms == ABBE_TERMS) { /* constant after inlining: six statements, no loop */
        acc[0] += abbe_ld_f32_aligned(row) * b;
        acc[1] += abbe_ld_f32_aligned(row + 4) * b;
        acc[2] += abbe_ld_f32_aligned(row + 8) * b;
        acc[3] += abbe_ld_f32_aligned(row + 12) * b;
        acc[4] += abbe_ld_f32_aligned(row + 16) * b;
        acc[5] += abbe_ld_f32_aligned(row + 20) * b;
        return row + 4u * ABBE_TERMS;
    }
    for (unsigned col = 0; col < n_terms; col++) {
        acc[col] += abbe_ld_f32_aligned(row + 4u * col) * b;
    }
    return row + 4u * n_terms;
}

static ABBE_ALWAYS_INLINE void dot_axis_f32(const abbe_axis_model_t *ax, int32_t p, unsigned n_terms,
                                            float *restrict acc)
{
    const uint8_t *row = ax->coef_f32;
    if (ax->trend_rows > 0u) {
        float u = (float)abbe_arg_cheb_q30(ax, p) * 9.31322574615478515625e-10f; /* 2^-30 */
        float two_u = u + u;
        float t_prev = 1.0f, t = u;
        row = mac_row_f32(row, t_prev, n_terms, acc);
        if (ax->trend_rows > 1u) {
            row = mac_row_f32(row, t, n_terms, acc);
        }
        for (unsigned k = 2; k < ax->trend_rows; k++) {
            float t_next = two_u * t - t_prev;
            t_prev = t;
            t = t_next;
            row = mac_row_f32(row, t, n_terms, acc);
        }
    }
    for (unsigned blk = 0; blk < ABBE_BLOCKS; blk++) {
        if (ax->harmonics[blk] == 0u) {
            continue;
        }
        float s1, c1;
        abbe_sincos_f32(abbe_arg_phase_q32(ax, blk, p), &s1, &c1);
        float s = s1, c = c1;
        for (unsigned n = 1;; n++) {
            row = mac_row_f32(row, s, n_terms, acc);
            row = mac_row_f32(row, c, n_terms, acc);
            if (n == ax->harmonics[blk]) {
                break;
            }
            float sn = s * c1 + c * s1;
            c = c * c1 - s * s1;
            s = sn;
        }
    }
}

void abbe_axis_terms_f32(const abbe_axis_model_t *ax, int32_t pos_nm, float *restrict value,
                         uint32_t *flags)
{
    /* The travel check comes first: a position outside it is reported even
     * for an axis without fitted terms. */
    int32_t p = abbe_arg_clamp(ax, pos_nm, flags);
    for (unsigned t = 0; t < ABBE_TERMS; t++) {
        value[t] = 0.0f;
    }
    if (ax->n_terms == ABBE_TERMS) {
        /* accumulate in place (restrict: no aliasing with the table, so the
         * sums stay in registers and no second array is on the stack) */
        dot_axis_f32(ax, p, ABBE_TERMS, value);
        for (unsigned t = 0; t < ABBE_TERMS; t++) {
            value[t] *= t < 3u ? UM_PER_LIN_LSB : URAD_PER_ANG_LSB;
        }
        return;
    }
    if (ax->n_terms == 0u) {
        return;
    }
    /* Sparse axis: accumulate packed into value[0 .. n_terms), then spread in
     * place from the last term down (column[t] <= t, so no source is
     * overwritten before it is read). */
    dot_axis_f32(ax, p, ax->n_terms, value);
    for (unsigned t = ABBE_TERMS; t-- > 0u;) {
        uint8_t col = ax->column[t];
        value[t] = col == 0xFFu ? 0.0f : value[col] * (t < 3u ? UM_PER_LIN_LSB : URAD_PER_ANG_LSB);
    }
}

abbe_status_t abbe_mm_to_nm_f32(float mm, int32_t *nm, uint32_t *flags)
{
    if (abbe_f32_nonfinite(mm)) {
        return ABBE_E_INPUT;
    }
    /* Beyond +/-2147 mm the nm value would not fit int32. */
    if (mm > 2147.0f) {
        mm = 2147.0f;
        *flags |= ABBE_FLAG_OUT_OF_TRAVEL;
    } else if (mm < -2147.0f) {
        mm = -2147.0f;
        *flags |= ABBE_FLAG_OUT_OF_TRAVEL;
    }
    /* Split into whole mm (exact) and a fraction (exact, |f| < 1): the fraction's
     * product with 1e6 rounds by at most 0.06 nm, where mm * 1e6 would lose 64 nm. */
    int32_t whole = (int32_t)mm;
    float frac = mm - (float)whole;
    float sub = frac * 1.0e6f;
    int32_t sub_nm = (int32_t)(sub + (sub >= 0.0f ? 0.5f : -0.5f));
    *nm = whole * 1000000 + sub_nm;
    return ABBE_OK;
}
