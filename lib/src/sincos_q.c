/* abbe: sin and cos of a phase in Q30, integer only.
 *
 * One function out of line, shared by both per-axis kernels (terms_q.c,
 * terms_sparse_q.c): once per Fourier block and call, so the call costs a few
 * instructions per block, and having it once rather than inlined in each kernel
 * saves its code twice. Its sine and cosine come back as one uint64 (r0:r1 on a
 * Cortex-M) rather than through pointers, which keeps its frame to the
 * registers it saves; built -Os on the Cortex-M for the same reason (20 B of
 * stack instead of 56: GCC's -O2 schedule loads all nine constants up front).
 *
 * The phase (fraction of a turn, Q32) is reduced to the nearest quarter turn,
 * leaving r in [-1/8, 1/8) turn; sin and cos of r come from near-minimax
 * polynomials in u = 8r (|u| <= 1), and the quarter index rotates them.
 *
 * Horner in block floating point: with z = u^2 in Q30, each step
 *     p <- C_k + hi32(p * z + 2^31)
 * is one 32 x 32 + 64 multiply-accumulate (SMLAL with C_k in the high word)
 * and loses 2 fractional bits, so each coefficient is stored 2 bits coarser
 * than the one before (S: Q37..Q31, C: Q38..Q32) and the last step lands on
 * Q30 (cos) or on Q31 for u * S(z) -> Q30 (sin). Every step rounds to nearest.
 * Coefficients: weighted least squares on 20000 Chebyshev nodes refined by
 * Lawson iteration (minimax), then rounded to their formats. Approximation
 * error 1.2e-9 (sin) and 5e-11 (cos); measured total error below 2 LSB
 * (tests/unit/test_eval.c, docs/numerics.md). */
#include "internal.h"

/* hi32(p * z) + c, rounded: c in the high word and 2^31 in the low word of
 * the 64-bit accumulator, one multiply-accumulate. The accumulator is formed
 * by arithmetic (c 2^32 + 2^31: the same bits, the same code), not by
 * converting the uint64 of those bits, which for a negative c is out of
 * int64's range (implementation-defined, docs/proofs.md "Signed downcasts"). */
static ABBE_ALWAYS_INLINE int32_t abbe_horner_step(int32_t c, int32_t p, int32_t z)
{
    int64_t acc = (int64_t)c * ((int64_t)1 << 32) + ((int64_t)1 << 31);
    return (int32_t)(abbe_smlal(acc, p, z) >> 32);
}

uint64_t abbe_sincos_q30_pair(uint32_t phase_q32)
{
    uint32_t quarter = ((phase_q32 + 0x20000000u) >> 30) & 3u;
    /* r = phase - quarter turns in [-2^29, 2^29); u = r / 2^29 in Q31 = 4 r,
     * shifted as uint32 (the same bits as the int32 product, which cannot
     * overflow, but without a product a proof must bound) */
    int32_t u_q31 = abbe_u32_to_i32((phase_q32 - (quarter << 30)) << 2);
    int32_t z_q30 = abbe_horner_step(0, u_q31, u_q31);        /* u^2: Q62 -> Q30, <= 2^30 */

    int32_t ps = -4930933;                        /* S3, Q37 */
    ps = abbe_horner_step(85551349, ps, z_q30);   /* S2, Q35 */
    ps = abbe_horner_step(-693597423, ps, z_q30); /* S1, Q33 */
    ps = abbe_horner_step(1686629690, ps, z_q30); /* S0, Q31 */
    int32_t s = abbe_horner_step(0, u_q31, ps);   /* u S(z): Q62 -> Q30 */

    int32_t c = 970267;                           /* C4, Q38 */
    c = abbe_horner_step(-22398331, c, z_q30);    /* C3, Q36 */
    c = abbe_horner_step(272375234, c, z_q30);    /* C2, Q34 */
    c = abbe_horner_step(-1324675869, c, z_q30);  /* C1, Q32 */
    c = abbe_horner_step(ABBE_Q30_ONE, c, z_q30); /* C0 = 1, Q30 */

    /* quarter 0: (s, c), 1: (c, -s), 2: (-s, -c), 3: (-c, s); |s|, |c| <= 2^30.
     * With masks rather than selects, so no compiler turns them into branches:
     * the run time stays independent of the phase. */
    uint32_t swap = 0u - (quarter & 1u);                    /* all ones: swap */
    uint32_t neg_s = 0u - ((quarter >> 1) & 1u);            /* all ones: negate */
    uint32_t neg_c = 0u - (((quarter + 1u) >> 1) & 1u);
    uint32_t us = (uint32_t)s, uc = (uint32_t)c, x = (us ^ uc) & swap;
    uint32_t sin_bits = ((us ^ x) ^ neg_s) - neg_s; /* (v ^ m) - m: v or -v */
    uint32_t cos_bits = ((uc ^ x) ^ neg_c) - neg_c;
    return (uint64_t)sin_bits | ((uint64_t)cos_bits << 32);
}

void abbe_sincos_q30(uint32_t phase_q32, int32_t *sin_q30, int32_t *cos_q30)
{
    const uint64_t pair = abbe_sincos_q30_pair(phase_q32);
    *sin_q30 = abbe_q30_of_bits((uint32_t)pair);
    *cos_q30 = abbe_q30_of_bits((uint32_t)(pair >> 32));
}
