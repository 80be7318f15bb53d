/* abbe: fitted term values of one axis, fixed point.
 *
 * The basis is streamed: each Chebyshev row (by recurrence) or harmonic (by
 * rotating the block's one sin/cos) is produced and at once multiplied into
 * the term accumulators, so no basis array exists. Coefficients are read in
 * place. Each term accumulates exactly in int64 (one SMLAL per coefficient on
 * a Cortex-M): sum |c| <= 2^32 (linear) or 2^28 (angular), validated by the
 * loader, times |b| <= 2^30 (+ a few LSB) stays below 2^63.
 *
 * The accumulators start at the rounding constant of their final shift, so
 * the result needs no separate rounding: linear terms are the high word
 * (2^-38 nm -> 2^-6 nm, |value| <= 2^30), angular terms the sum shifted by 31
 * (2^-66 rad -> 2^-35 rad, |value| <= 2^27). A fitted axis has all six terms;
 * that case is compiled with a constant column count so the accumulators stay
 * in registers, and sparse axes share the code with a run-time count.
 */
#include "basis_q.h"

/* A fitted axis: six columns, the accumulators in registers. */
ABBE_NOINLINE static void terms6_q(const abbe_axis_model_t *ax, uint32_t d, int32_t value[ABBE_TERMS])
{
    const uint8_t *row = ax->coef_q;
    int64_t a0 = LIN_BIAS, a1 = LIN_BIAS, a2 = LIN_BIAS, a3 = ANG_BIAS, a4 = ANG_BIAS, a5 = ANG_BIAS;
#define ROW6(b)                                                                            \
    do {                                                                                   \
        const int32_t b_ = (b);                                                            \
        MAC(a0, 0, b_); MAC(a1, 1, b_); MAC(a2, 2, b_);                                    \
        MAC(a3, 3, b_); MAC(a4, 4, b_); MAC(a5, 5, b_);                                    \
        row += 24;                                                                         \
    } while (0)
#define FIRST6()                                                                           \
    do {                                                                                   \
        MAC1(a0, 0); MAC1(a1, 1); MAC1(a2, 2); MAC1(a3, 3); MAC1(a4, 4); MAC1(a5, 5);      \
        row += 24;                                                                         \
    } while (0)
    ABBE_BASIS_Q(ax, d, FIRST6, ROW6);
#undef FIRST6
#undef ROW6
    value[0] = (int32_t)(a0 >> LIN_SHIFT);
    value[1] = (int32_t)(a1 >> LIN_SHIFT);
    value[2] = (int32_t)(a2 >> LIN_SHIFT);
    value[3] = (int32_t)(a3 >> ANG_SHIFT);
    value[4] = (int32_t)(a4 >> ANG_SHIFT);
    value[5] = (int32_t)(a5 >> ANG_SHIFT);
}

void abbe_axis_terms_q(const abbe_axis_model_t *ax, uint32_t d, int32_t value[ABBE_TERMS])
{
    if (ax->n_terms == ABBE_TERMS) {
        terms6_q(ax, d, value);
    } else {
        abbe_axis_terms_sparse_q(ax, d, value);
    }
}
