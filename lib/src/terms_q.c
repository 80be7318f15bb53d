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
#include "sincos_q.h"

#define LIN_SHIFT (38 - ABBE_TERM_LIN_Q_BITS) /* 32: the high word */
#define ANG_SHIFT (66 - ABBE_TERM_ANG_Q_BITS) /* 31 */
#define LIN_BIAS ((int64_t)1 << (LIN_SHIFT - 1))
#define ANG_BIAS ((int64_t)1 << (ANG_SHIFT - 1))

/* (a b + c d) / 2^30, rounded once: Q30 x Q30 + Q30 x Q30 -> Q30. */
static ABBE_ALWAYS_INLINE int32_t dot2_q30(int32_t a, int32_t b, int32_t c, int32_t d)
{
    return (int32_t)(((int64_t)a * b + (int64_t)c * d + ((int64_t)1 << 29)) >> 30);
}

/* The basis rows of one axis, in table order, each handed to ROW(b) (Q30) as
 * it is produced: T_0 = 1, T_1 = u, T_k by recurrence; then per Fourier block
 * sin/cos of harmonic 1 (one polynomial evaluation) and the higher harmonics
 * by rotating with the fundamental. A macro so that each kernel below gets it
 * inlined around its own accumulators. */
#define ABBE_BASIS_Q(ax, d, FIRST_ROW, ROW)                                                \
    do {                                                                                   \
        const unsigned trend_rows_ = (ax)->trend_rows;                                     \
        if (trend_rows_ > 0u) {                                                            \
            FIRST_ROW();                                                                   \
            if (trend_rows_ > 1u) {                                                        \
                const int32_t u_ = abbe_arg_cheb_q30((ax), (d));                           \
                int32_t t_prev_ = ABBE_Q30_ONE, t_ = u_;                                   \
                ROW(t_);                                                                   \
                for (unsigned k_ = 2; k_ < trend_rows_; k_++) {                            \
                    /* T_k = 2u T_(k-1) - T_(k-2); |T_k| <= 1 on [-1, 1] */                \
                    int32_t t_next_ = (int32_t)((((int64_t)u_ * t_ + ((int64_t)1 << 28)) >> 29) - t_prev_); \
                    t_prev_ = t_;                                                          \
                    t_ = t_next_;                                                          \
                    ROW(t_);                                                               \
                }                                                                          \
            }                                                                              \
        }                                                                                  \
        for (unsigned blk_ = 0; blk_ < ABBE_BLOCKS; blk_++) {                              \
            const unsigned h_ = (ax)->harmonics[blk_];                                     \
            if (h_ == 0u) {                                                                \
                continue;                                                                  \
            }                                                                              \
            int32_t s1_, c1_;                                                              \
            abbe_sincos_q30_inline(abbe_arg_phase_q32((ax), blk_, (d)), &s1_, &c1_);       \
            const int32_t ns1_ = -s1_;                                                     \
            int32_t s_ = s1_, c_ = c1_;                                                    \
            for (unsigned n_ = 1;; n_++) {                                                 \
                ROW(s_);                                                                   \
                ROW(c_);                                                                   \
                if (n_ == h_) {                                                            \
                    break;                                                                 \
                }                                                                          \
                /* next harmonic: rotate (s, c) by the fundamental */                      \
                int32_t sn_ = dot2_q30(s_, c1_, c_, s1_);                                  \
                c_ = dot2_q30(c_, c1_, s_, ns1_);                                          \
                s_ = sn_;                                                                  \
            }                                                                              \
        }                                                                                  \
    } while (0)

#define LD(k) abbe_ld_i32(row + 4u * (k))
#define MAC(acc, k, b) acc += (int64_t)LD(k) * (b)
/* T_0 = 1 (2^30): with a constant basis GCC would turn each multiply-add into
 * a 64-bit shift sequence of seven instructions; this keeps the one SMLAL. */
#define MAC1(acc, k) acc = abbe_smlal(acc, LD(k), ABBE_Q30_ONE)

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

/* A sparse axis (n_terms < 6 packed columns, column col holding the col-th
 * present term): rare, so built for a small stack and little code rather
 * than for speed: one column at a time, each with its own pass of the basis
 * and a single accumulator. */
ABBE_NOINLINE static void terms_sparse_q(const abbe_axis_model_t *ax, uint32_t d, int32_t value[ABBE_TERMS])
{
    const unsigned stride = 4u * ax->n_terms;
    for (unsigned t = 0; t < ABBE_TERMS; t++) {
        const unsigned col = ax->column[t];
        /* no basis rows: no coefficient array either (NULL), every term is 0 */
        if (col == 0xFFu || ax->n_basis == 0u) {
            value[t] = 0;
            continue;
        }
        const uint8_t *row = ax->coef_q + 4u * col;
        /* linear or angular: shifts 32 or 31, computed (a select here would
         * let the compiler duplicate the whole loop) */
        const unsigned shift = (unsigned)LIN_SHIFT - (unsigned)(t >= 3u);
        int64_t acc = (int64_t)1 << (shift - 1u);
#define FIRST1() do { MAC1(acc, 0); row += stride; } while (0)
#define ROW1(b) do { MAC(acc, 0, (b)); row += stride; } while (0)
        ABBE_BASIS_Q(ax, d, FIRST1, ROW1);
#undef FIRST1
#undef ROW1
        value[t] = (int32_t)(acc >> shift);
    }
}

#undef MAC
#undef MAC1
#undef LD

void abbe_axis_terms_q(const abbe_axis_model_t *ax, uint32_t d, int32_t value[ABBE_TERMS])
{
    if (ax->n_terms == ABBE_TERMS) {
        terms6_q(ax, d, value);
    } else {
        terms_sparse_q(ax, d, value);
    }
}
