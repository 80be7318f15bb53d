/* abbe: the fixed-point basis of one axis, streamed, and the rounding of
 * the term sums: shared by the six-term kernel (terms_q.c) and the sparse one
 * (terms_sparse_q.c), which differ only in what they do with each row. Not
 * installed. */
#ifndef ABBE_BASIS_Q_H
#define ABBE_BASIS_Q_H

#include "internal.h"

#define LIN_SHIFT (38 - ABBE_TERM_LIN_Q_BITS) /* 32: the high word */
#define ANG_SHIFT (66 - ABBE_TERM_ANG_Q_BITS) /* 31 */
#define LIN_BIAS ((int64_t)1 << (LIN_SHIFT - 1))
#define ANG_BIAS ((int64_t)1 << (ANG_SHIFT - 1))

/* (a b + c d) / 2^30, rounded once: Q30 x Q30 + Q30 x Q30 -> Q30, as int64;
 * dot2_q30 converts it to int32. Only the harmonics' rotation uses it (the
 * basis below), whose rows stay within +/-(2^30 + 16): the hypothesis
 * sincos_range, which tests/proofs/hypotheses.c checks on this int64 value
 * for every phase, so the conversion is always in range. */
static ABBE_ALWAYS_INLINE int64_t dot2_wide_q30(int32_t a, int32_t b, int32_t c, int32_t d)
{
    return ((int64_t)a * b + (int64_t)c * d + ((int64_t)1 << 29)) >> 30;
}

static ABBE_ALWAYS_INLINE int32_t dot2_q30(int32_t a, int32_t b, int32_t c, int32_t d)
{
    const int64_t r = dot2_wide_q30(a, b, c, d);
    /*@ assert sincos_range: -1073741840 <= r <= 1073741840; */
    return (int32_t)r;
}

/* The next Chebyshev row, Q30: T_k = 2u T_(k-1) - T_(k-2), rounded once, as
 * int64; cheb_next_q30 converts it to int32. |T_k| <= 1 on [-1, 1], in Q30
 * within 2^30 + a few LSB of rounding: the hypothesis cheb_rows, which
 * tests/proofs/hypotheses.c checks on this int64 value for every u in
 * [-2^30, 2^30] and rows T_2..T_7 (the trend's and the reversal block's rows:
 * eval_q.c), so the conversion is always in range. */
static ABBE_ALWAYS_INLINE int64_t cheb_next_wide_q30(int32_t u, int32_t t, int32_t t_prev)
{
    return (((int64_t)u * t + ((int64_t)1 << 28)) >> 29) - t_prev;
}

static ABBE_ALWAYS_INLINE int32_t cheb_next_q30(int32_t u, int32_t t, int32_t t_prev)
{
    const int64_t r = cheb_next_wide_q30(u, t, t_prev);
    /*@ assert cheb_rows: -1073741840 <= r <= 1073741840; */
    return (int32_t)r;
}

/* The basis rows of one axis, in table order, each handed to ROW(b) (Q30) as
 * it is produced: T_0 = 1, T_1 = u, T_k by recurrence; then per Fourier block
 * sin/cos of harmonic 1 (abbe_sincos_q30_pair, sincos_q.c) and the higher
 * harmonics by rotating with the fundamental. A macro so that each kernel gets
 * it inlined around its own accumulators. */
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
                    int32_t t_next_ = cheb_next_q30(u_, t_, t_prev_);                     \
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
            const uint64_t sc_ = abbe_sincos_q30_pair(abbe_arg_phase_q32((ax), blk_, (d)));  \
            const int32_t s1_ = abbe_q30_of_bits((uint32_t)sc_);                           \
            const int32_t c1_ = abbe_q30_of_bits((uint32_t)(sc_ >> 32));                   \
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

#define LD(k) abbe_ld_i32_aligned(row + 4u * (k))
#define MAC(acc, k, b) acc += (int64_t)LD(k) * (b)
/* T_0 = 1 (2^30): with a constant basis GCC would turn each multiply-add into
 * a 64-bit shift sequence of seven instructions; this keeps the one SMLAL. */
#define MAC1(acc, k) acc = abbe_smlal(acc, LD(k), ABBE_Q30_ONE)

#endif /* ABBE_BASIS_Q_H */
