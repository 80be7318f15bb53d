/* abbe: fitted term values of one axis, single precision.
 *
 * The argument reduction is integer (internal.h: one offset d per axis, from
 * which the Chebyshev argument and the Fourier phases follow); the basis and
 * the dot products are float. The basis is streamed: each Chebyshev row (by
 * recurrence) or harmonic (by rotating the block's one sin/cos) is produced
 * and at once multiplied into the term accumulators, so no basis array
 * exists. The float32 coefficients are the int32 coefficients converted (same
 * units: 2^-8 nm, 2^-36 rad), and the values stay in those units: the caller
 * scales each once, folded into the lever arms of Eq. 3.
 */
#include "kernel_f32_sse2.h"
#include "sincos_f32.h"

/* The basis rows of one axis, in table order, each handed to ROW(b) as it is
 * produced: T_0 = 1 (FIRST_ROW()), T_1 = u, T_k by recurrence; then per
 * Fourier block sin/cos of harmonic 1 (one polynomial evaluation) and the
 * higher harmonics by rotating with the fundamental. A macro so that each
 * kernel below gets it inlined around its own accumulators. */
#define ABBE_BASIS_F32(ax, d, FIRST_ROW, ROW)                                              \
    do {                                                                                   \
        const unsigned trend_rows_ = (ax)->trend_rows;                                     \
        if (trend_rows_ > 0u) {                                                            \
            FIRST_ROW();                                                                   \
            if (trend_rows_ > 1u) {                                                        \
                const float u_ = (float)abbe_arg_cheb_q30((ax), (d)) * 9.31322574615478515625e-10f; \
                const float two_u_ = u_ + u_;                                              \
                float t_prev_ = 1.0f, t_ = u_;                                             \
                ROW(t_);                                                                   \
                for (unsigned k_ = 2; k_ < trend_rows_; k_++) {                            \
                    float t_next_ = two_u_ * t_ - t_prev_; /* T_k = 2u T_(k-1) - T_(k-2) */ \
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
            float s1_, c1_;                                                                \
            abbe_sincos_f32_inline(abbe_arg_phase_q32((ax), blk_, (d)), &s1_, &c1_);       \
            float s_ = s1_, c_ = c1_;                                                      \
            for (unsigned n_ = 1;; n_++) {                                                 \
                ROW(s_);                                                                   \
                ROW(c_);                                                                   \
                if (n_ == h_) {                                                            \
                    break;                                                                 \
                }                                                                          \
                float sn_ = s_ * c1_ + c_ * s1_; /* next harmonic: rotate */               \
                c_ = c_ * c1_ - s_ * s1_;                                                  \
                s_ = sn_;                                                                  \
            }                                                                              \
        }                                                                                  \
    } while (0)

#define LD(k) abbe_ld_f32_aligned(row + 4u * (k))

#if defined(ABBE_F32_SSE2)
/* x86-64: the kernel of eval_f32_sse2.c, with each block's fundamental from
 * the scalar sin/cos (this path serves abbe_term_eval_f32). */
static void terms6_f32(const abbe_axis_model_t *ax, uint32_t d, float value[ABBE_TERMS])
{
    __m128 h[ABBE_BLOCKS];
    for (unsigned blk = 0; blk < ABBE_BLOCKS; blk++) {
        float s1, c1;
        abbe_sincos_f32_inline(abbe_arg_phase_q32(ax, blk, d), &s1, &c1);
        h[blk] = _mm_setr_ps(s1, c1, s1, c1);
    }
    __m128 lo, hi;
    const float u = (float)abbe_arg_cheb_q30(ax, d) * 9.31322574615478515625e-10f; /* 2^-30 */
    abbe_axis6_sse2(abbe_x86_consts(), ax, _mm_set1_ps(u), h[0], h[1], &lo, &hi);
    _mm_storeu_ps(value, lo);
    abbe_st2(value + 4, hi);
}

#else /* !ABBE_F32_SSE2 */

/* A fitted axis: six columns, the accumulators in registers. */
ABBE_NOINLINE static void terms6_f32(const abbe_axis_model_t *ax, uint32_t d, float value[ABBE_TERMS])
{
    const uint8_t *row = ax->coef_f32;
    float a0 = 0.0f, a1 = 0.0f, a2 = 0.0f, a3 = 0.0f, a4 = 0.0f, a5 = 0.0f;
#define FIRST6() \
    do { a0 = LD(0); a1 = LD(1); a2 = LD(2); a3 = LD(3); a4 = LD(4); a5 = LD(5); row += 24; } while (0)
#if defined(__GNUC__) && defined(__thumb2__) && defined(__ARM_FP) && (__ARM_FP & 4) && defined(__ARMEL__) && \
    !defined(ABBE_PORTABLE_C)
/* Cortex-M4F: one VLDM brings the row's six coefficients into s8-s13
 * (GCC never combines VLDRs), then six fused multiply-adds: 7 instructions
 * per row instead of 12. Rows are 4-byte aligned (ABBE_E_ALIGN). */
#define ROW6(bv_)                                                                            \
    __asm__("vldmia %[p]!, {s8-s13}\n\t"                                                   \
            "vfma.f32 %[a0], s8, %[bb]\n\t"                                                 \
            "vfma.f32 %[a1], s9, %[bb]\n\t"                                                 \
            "vfma.f32 %[a2], s10, %[bb]\n\t"                                                \
            "vfma.f32 %[a3], s11, %[bb]\n\t"                                                \
            "vfma.f32 %[a4], s12, %[bb]\n\t"                                                \
            "vfma.f32 %[a5], s13, %[bb]"                                                    \
            : [a0] "+t"(a0), [a1] "+t"(a1), [a2] "+t"(a2), [a3] "+t"(a3), [a4] "+t"(a4),   \
              [a5] "+t"(a5), [p] "+r"(row)                                                 \
            : [bb] "t"(bv_), "m"(*(const struct { uint8_t bytes[24]; } *)row)                \
            : "s8", "s9", "s10", "s11", "s12", "s13")
#else
#define ROW6(b)                                                                            \
    do {                                                                                   \
        const float b_ = (b);                                                              \
        a0 += LD(0) * b_; a1 += LD(1) * b_; a2 += LD(2) * b_;                              \
        a3 += LD(3) * b_; a4 += LD(4) * b_; a5 += LD(5) * b_;                              \
        row += 24;                                                                         \
    } while (0)
#endif
    ABBE_BASIS_F32(ax, d, FIRST6, ROW6);
#undef FIRST6
#undef ROW6
    value[0] = a0;
    value[1] = a1;
    value[2] = a2;
    value[3] = a3;
    value[4] = a4;
    value[5] = a5;
}

#endif /* ABBE_F32_SSE2 */

/* A sparse axis (n_terms < 6 packed columns): rare, so built for a small
 * stack and little code rather than for speed: one column at a time, each
 * with its own pass of the basis and a single accumulator. */
ABBE_NOINLINE static void terms_sparse_f32(const abbe_axis_model_t *ax, uint32_t d, float value[ABBE_TERMS])
{
    const unsigned stride = 4u * ax->n_terms;
    for (unsigned t = 0; t < ABBE_TERMS; t++) {
        const unsigned col = ax->column[t];
        /* no basis rows: no coefficient array either (NULL), every term is 0 */
        if (col == 0xFFu || ax->n_basis == 0u) {
            value[t] = 0.0f;
            continue;
        }
        const uint8_t *row = ax->coef_f32 + 4u * col;
        float acc = 0.0f;
#define FIRST1() do { acc = LD(0); row += stride; } while (0)
#define ROW1(b) do { acc += LD(0) * (b); row += stride; } while (0)
        ABBE_BASIS_F32(ax, d, FIRST1, ROW1);
#undef FIRST1
#undef ROW1
        value[t] = acc;
    }
}

#undef LD

void abbe_axis_terms_f32(const abbe_axis_model_t *ax, uint32_t d, float value[ABBE_TERMS])
{
    if (ax->n_terms == ABBE_TERMS) {
        terms6_f32(ax, d, value);
    } else {
        terms_sparse_f32(ax, d, value);
    }
}

abbe_status_t abbe_mm_to_nm_f32(float mm, int32_t *nm, uint32_t *flags)
{
    return abbe_mm_to_nm_inline(mm, nm, flags) ? ABBE_E_INPUT : ABBE_OK;
}
