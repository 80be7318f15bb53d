/* abbe: fitted term values of one axis, single precision.
 *
 * Same structure as terms_q.c; the argument reduction stays integer (arg.c),
 * the basis and the dot products are float. Coefficients are the table's
 * float32 array (um, urad), read in place.
 */
#include "internal.h"

static unsigned basis_f32(const abbe_axis_model_t *ax, int32_t p, float basis[ABBE_MAX_BASIS])
{
    unsigned k = 0;
    if (ax->trend_rows > 0u) {
        float u = (float)abbe_arg_cheb_q30(ax, p) * 9.31322574615478515625e-10f; /* 2^-30 */
        float two_u = u + u;
        basis[k++] = 1.0f;
        if (ax->trend_rows > 1u) {
            basis[k++] = u;
        }
        for (unsigned i = 2; i < ax->trend_rows; i++, k++) {
            basis[k] = two_u * basis[k - 1u] - basis[k - 2u];
        }
    }
    for (unsigned b = 0; b < ABBE_BLOCKS; b++) {
        if (ax->harmonics[b] == 0u) {
            continue;
        }
        float s1, c1;
        abbe_sincos_f32(abbe_arg_phase_q32(ax, b, p), &s1, &c1);
        float s = s1, c = c1;
        basis[k++] = s;
        basis[k++] = c;
        for (unsigned n = 2; n <= ax->harmonics[b]; n++) {
            float sn = s * c1 + c * s1;
            c = c * c1 - s * s1;
            s = sn;
            basis[k++] = s;
            basis[k++] = c;
        }
    }
    return k;
}

/* acc[col] = sum over rows of coef[row][col] * basis[row]. A fitted axis has
 * all six terms: that case keeps six accumulators in registers (and lets the
 * compiler use SIMD); sparse axes take the generic loop. */
static void dot_rows_f32(const uint8_t *row, const float *basis, unsigned rows, unsigned n_terms,
                         float acc[ABBE_TERMS])
{
    if (n_terms == ABBE_TERMS) {
        float a0 = 0.0f, a1 = 0.0f, a2 = 0.0f, a3 = 0.0f, a4 = 0.0f, a5 = 0.0f;
        for (unsigned r = 0; r < rows; r++, row += 4u * ABBE_TERMS) {
            float b = basis[r];
            a0 += abbe_ld_f32(row) * b;
            a1 += abbe_ld_f32(row + 4) * b;
            a2 += abbe_ld_f32(row + 8) * b;
            a3 += abbe_ld_f32(row + 12) * b;
            a4 += abbe_ld_f32(row + 16) * b;
            a5 += abbe_ld_f32(row + 20) * b;
        }
        acc[0] = a0;
        acc[1] = a1;
        acc[2] = a2;
        acc[3] = a3;
        acc[4] = a4;
        acc[5] = a5;
        return;
    }
    for (unsigned r = 0; r < rows; r++) {
        for (unsigned col = 0; col < n_terms; col++, row += 4) {
            acc[col] += abbe_ld_f32(row) * basis[r];
        }
    }
}

void abbe_axis_terms_f32(const abbe_axis_model_t *ax, int32_t pos_nm, float value[ABBE_TERMS],
                         uint32_t *flags)
{
    for (unsigned t = 0; t < ABBE_TERMS; t++) {
        value[t] = 0.0f;
    }
    /* The travel check comes first: a position outside it is reported even
     * for an axis without fitted terms. */
    int32_t p = abbe_arg_clamp(ax, pos_nm, flags);
    if (ax->n_terms == 0u || ax->coef_f32 == NULL) {
        return;
    }
    float basis[ABBE_MAX_BASIS];
    unsigned rows = basis_f32(ax, p, basis);

    if (ax->n_terms == ABBE_TERMS) { /* columns are the terms: no scatter */
        dot_rows_f32(ax->coef_f32, basis, rows, ABBE_TERMS, value);
        return;
    }
    float acc[ABBE_TERMS] = {0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f};
    dot_rows_f32(ax->coef_f32, basis, rows, ax->n_terms, acc);
    for (unsigned t = 0; t < ABBE_TERMS; t++) {
        if (ax->column[t] != 0xFFu) {
            value[t] = acc[ax->column[t]];
        }
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
