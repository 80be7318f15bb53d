/* abbe: fitted term values of one axis, fixed point.
 *
 * The basis is streamed: each Chebyshev row (by recurrence) or harmonic (by
 * rotating the block's one sin/cos) is produced and immediately multiplied
 * into the term accumulators, so no basis array lives on the stack.
 * Coefficients are read in place. A fitted axis has all six terms; that case
 * is compiled with a constant column count so the accumulators stay in
 * registers, and sparse axes share the same code with a run-time count.
 */
#include "internal.h"

/* acc[col] += coef[row][col] * b. Sum of |c| <= 2^32 (validated) times
 * |b| <= 2^30 stays below 2^63. */
static ABBE_ALWAYS_INLINE const uint8_t *mac_row_q(const uint8_t *row, int32_t b, unsigned n_terms,
                                                    int64_t *restrict acc)
{
    if (n_terms == ABBE_TERMS) { /* constant after inlining: six statements, no loop */
        acc[0] += (int64_t)abbe_ld_i32(row) * b;
        acc[1] += (int64_t)abbe_ld_i32(row + 4) * b;
        acc[2] += (int64_t)abbe_ld_i32(row + 8) * b;
        acc[3] += (int64_t)abbe_ld_i32(row + 12) * b;
        acc[4] += (int64_t)abbe_ld_i32(row + 16) * b;
        acc[5] += (int64_t)abbe_ld_i32(row + 20) * b;
        return row + 4u * ABBE_TERMS;
    }
    for (unsigned col = 0; col < n_terms; col++) {
        acc[col] += (int64_t)abbe_ld_i32(row + 4u * col) * b;
    }
    return row + 4u * n_terms;
}

static ABBE_ALWAYS_INLINE void dot_axis_q(const abbe_axis_model_t *ax, int32_t p, unsigned n_terms,
                                          int64_t *restrict acc)
{
    const uint8_t *row = ax->coef_q;
    if (ax->trend_rows > 0u) {
        int32_t u = abbe_arg_cheb_q30(ax, p);
        int32_t t_prev = ABBE_Q30_ONE, t = u;
        row = mac_row_q(row, t_prev, n_terms, acc);
        if (ax->trend_rows > 1u) {
            row = mac_row_q(row, t, n_terms, acc);
        }
        for (unsigned k = 2; k < ax->trend_rows; k++) {
            /* T_k = 2u T_(k-1) - T_(k-2); |T_k| <= 1 on [-1, 1] */
            int32_t t_next = (int32_t)(abbe_shr_round(2 * (int64_t)u * t, 30u) - t_prev);
            t_prev = t;
            t = t_next;
            row = mac_row_q(row, t, n_terms, acc);
        }
    }
    for (unsigned blk = 0; blk < ABBE_BLOCKS; blk++) {
        if (ax->harmonics[blk] == 0u) {
            continue;
        }
        int32_t s1, c1;
        abbe_sincos_q30(abbe_arg_phase_q32(ax, blk, p), &s1, &c1);
        int32_t s = s1, c = c1;
        for (unsigned n = 1;; n++) {
            row = mac_row_q(row, s, n_terms, acc);
            row = mac_row_q(row, c, n_terms, acc);
            if (n == ax->harmonics[blk]) {
                break;
            }
            /* next harmonic: rotate (s, c) by the fundamental */
            int64_t sn = (int64_t)s * c1 + (int64_t)c * s1;
            int64_t cn = (int64_t)c * c1 - (int64_t)s * s1;
            s = (int32_t)abbe_shr_round(sn, 30u);
            c = (int32_t)abbe_shr_round(cn, 30u);
        }
    }
}

void abbe_axis_terms_q(const abbe_axis_model_t *ax, int32_t pos_nm, int64_t *restrict value,
                       uint32_t *flags)
{
    /* The travel check comes first: a position outside it is reported even
     * for an axis without fitted terms. */
    int32_t p = abbe_arg_clamp(ax, pos_nm, flags);
    /* element by element: an aggregate initialiser or a loop becomes a memset
     * call on ARM, a byte loop in newlib-nano (150 instructions per axis) */
    value[0] = 0;
    value[1] = 0;
    value[2] = 0;
    value[3] = 0;
    value[4] = 0;
    value[5] = 0;
    if (ax->n_terms == ABBE_TERMS) {
        /* accumulate in place (restrict: no aliasing with the table) */
        dot_axis_q(ax, p, ABBE_TERMS, value);
        for (unsigned t = 0; t < ABBE_TERMS; t++) {
            value[t] = abbe_shr_round(value[t], 30u);
        }
        return;
    }
    if (ax->n_terms == 0u) {
        return;
    }
    /* Sparse axis: packed into value[0 .. n_terms), spread in place from the
     * last term down (column[t] <= t: no source is overwritten early). */
    dot_axis_q(ax, p, ax->n_terms, value);
    for (unsigned t = ABBE_TERMS; t-- > 0u;) {
        uint8_t col = ax->column[t];
        value[t] = col == 0xFFu ? 0 : abbe_shr_round(value[col], 30u);
    }
}
