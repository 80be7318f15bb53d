/* abbe: fitted term values of one axis, fixed point.
 *
 * Builds the axis' basis once (Chebyshev rows by recurrence, one sin/cos per
 * Fourier block and its harmonics by rotation), then every present term is a
 * dot product of its column with the basis. Coefficients are read in place.
 */
#include "internal.h"

/* Rotate (s, c) by (s1, c1): the next harmonic, in Q30. */
static void rotate_q30(int32_t *s, int32_t *c, int32_t s1, int32_t c1)
{
    int64_t sn = (int64_t)*s * c1 + (int64_t)*c * s1;
    int64_t cn = (int64_t)*c * c1 - (int64_t)*s * s1;
    *s = (int32_t)abbe_shr_round(sn, 30u);
    *c = (int32_t)abbe_shr_round(cn, 30u);
}

static unsigned basis_q30(const abbe_axis_model_t *ax, int32_t p, int32_t basis[ABBE_MAX_BASIS])
{
    unsigned k = 0;
    if (ax->trend_rows > 0u) {
        int32_t u = abbe_arg_cheb_q30(ax, p);
        basis[k++] = ABBE_Q30_ONE;
        if (ax->trend_rows > 1u) {
            basis[k++] = u;
        }
        for (unsigned i = 2; i < ax->trend_rows; i++, k++) {
            /* T_i = 2u T_(i-1) - T_(i-2); |T_i| <= 1 on [-1, 1] */
            int64_t next = abbe_shr_round(2 * (int64_t)u * basis[k - 1u], 30u) - basis[k - 2u];
            basis[k] = (int32_t)next;
        }
    }
    for (unsigned b = 0; b < ABBE_BLOCKS; b++) {
        if (ax->harmonics[b] == 0u) {
            continue;
        }
        int32_t s1, c1;
        abbe_sincos_q30(abbe_arg_phase_q32(ax, b, p), &s1, &c1);
        int32_t s = s1, c = c1;
        basis[k++] = s;
        basis[k++] = c;
        for (unsigned n = 2; n <= ax->harmonics[b]; n++) {
            rotate_q30(&s, &c, s1, c1);
            basis[k++] = s;
            basis[k++] = c;
        }
    }
    return k;
}

/* acc[col] = sum over rows of coef[row][col] * basis[row], exact in int64.
 * Six-term axes (every fitted axis) keep the accumulators in registers. */
static void dot_rows_q(const uint8_t *row, const int32_t *basis, unsigned rows, unsigned n_terms,
                       int64_t acc[ABBE_TERMS])
{
    if (n_terms == ABBE_TERMS) {
        int64_t a0 = 0, a1 = 0, a2 = 0, a3 = 0, a4 = 0, a5 = 0;
        for (unsigned r = 0; r < rows; r++, row += 4u * ABBE_TERMS) {
            int64_t b = basis[r];
            a0 += abbe_ld_i32(row) * b;
            a1 += abbe_ld_i32(row + 4) * b;
            a2 += abbe_ld_i32(row + 8) * b;
            a3 += abbe_ld_i32(row + 12) * b;
            a4 += abbe_ld_i32(row + 16) * b;
            a5 += abbe_ld_i32(row + 20) * b;
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
            acc[col] += (int64_t)abbe_ld_i32(row) * basis[r];
        }
    }
}

void abbe_axis_terms_q(const abbe_axis_model_t *ax, int32_t pos_nm, int64_t value[ABBE_TERMS],
                       uint32_t *flags)
{
    for (unsigned t = 0; t < ABBE_TERMS; t++) {
        value[t] = 0;
    }
    /* The travel check comes first: a position outside it is reported even
     * for an axis without fitted terms. */
    int32_t p = abbe_arg_clamp(ax, pos_nm, flags);
    if (ax->n_terms == 0u || ax->coef_q == NULL) {
        return;
    }
    int32_t basis[ABBE_MAX_BASIS];
    unsigned rows = basis_q30(ax, p, basis);

    /* Sum of |c| <= 2^32 (validated) times |basis| <= 2^30: below 2^63. */
    int64_t acc[ABBE_TERMS] = {0, 0, 0, 0, 0, 0};
    dot_rows_q(ax->coef_q, basis, rows, ax->n_terms, acc);
    if (ax->n_terms == ABBE_TERMS) { /* columns are the terms: no scatter */
        for (unsigned t = 0; t < ABBE_TERMS; t++) {
            value[t] = abbe_shr_round(acc[t], 30u);
        }
        return;
    }
    for (unsigned t = 0; t < ABBE_TERMS; t++) {
        if (ax->column[t] != 0xFFu) {
            value[t] = abbe_shr_round(acc[ax->column[t]], 30u);
        }
    }
}
