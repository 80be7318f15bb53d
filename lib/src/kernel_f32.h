/* abbe: the single-precision per-axis kernel's parts, shared by the 3-axis
 * kernels (terms_f32.c) and the five-axis ones (terms_rot_f32.c): the basis
 * as a stream of rows, the row and harmonics macros (Cortex-M4F: inline
 * assembly), Eq. 3's fold and the six-term kernel's body. Each translation
 * unit instantiates the body once, so the 3-axis kernel's unit is what it
 * was before the five-axis one existed (bench/results.md, sections 5 and 11).
 * Not installed. */
#ifndef ABBE_KERNEL_F32_H
#define ABBE_KERNEL_F32_H

#include "kernel_f32_sse2.h"
#include "sincos_f32.h"


/* The basis rows of one axis, in table order, each handed to ROW(b) as it is
 * produced: T_0 = 1 (FIRST_ROW()), T_1 = u, T_k by recurrence; then per
 * Fourier block sin/cos of harmonic 1 (one polynomial evaluation) and the
 * higher harmonics by rotating with the fundamental. A macro so that each
 * kernel below gets it inlined around its own accumulators. */
#define ABBE_BASIS_F32(ax, d, NO_TREND, FIRST_ROW, ROW, HARMONICS)                         \
    do {                                                                                   \
        const unsigned trend_rows_ = (ax)->trend_rows;                                     \
        if (trend_rows_ == 0u) {                                                           \
            NO_TREND();                                                                    \
        } else {                                                                           \
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
            HARMONICS(s1_, c1_, h_);                                                       \
        }                                                                                  \
    } while (0)

/* The h >= 1 harmonics of a block as rows (sin, cos), from the fundamental
 * (s1, c1), each next one by rotating with it. */
#define ABBE_HARMONICS_C(ROW, s1, c1, h)                                                   \
    do {                                                                                   \
        float s_ = (s1), c_ = (c1);                                                        \
        for (unsigned n_ = (h);;) {                                                        \
            ROW(s_);                                                                       \
            ROW(c_);                                                                       \
            if (--n_ == 0u) {                                                              \
                break;                                                                     \
            }                                                                              \
            const float cn_ = c_ * (c1) - s_ * (s1); /* next harmonic: rotate */           \
            s_ = s_ * (c1) + c_ * (s1);                                                    \
            c_ = cn_;                                                                      \
        }                                                                                  \
    } while (0)

#define LD(k) abbe_ld_f32_aligned(row + 4u * (k))

/* (e_x, e_y, e_z) + lin [d_x, d_y, d_z] + [e_x, e_y, e_z] x r of an axis'
 * six values (a0..a5 = d_x, d_y, d_z, eps_x, eps_y, eps_z): Eq. 3's share of
 * the axis, r its lever arm (eval_f32.c). Nine multiply-adds. */
#define ABBE_FOLD6(e, r, lin, a0, a1, a2, a3, a4, a5)                                      \
    do {                                                                                   \
        (e).x += (lin) * (a0);                                                             \
        (e).x += (a4) * (r).z;                                                             \
        (e).x -= (a5) * (r).y;                                                             \
        (e).y += (lin) * (a1);                                                             \
        (e).y += (a5) * (r).x;                                                             \
        (e).y -= (a3) * (r).z;                                                             \
        (e).z += (lin) * (a2);                                                             \
        (e).z += (a3) * (r).y;                                                             \
        (e).z -= (a4) * (r).x;                                                             \
    } while (0)

#if defined(__GNUC__) && defined(__thumb2__) && defined(__ARM_FP) && (__ARM_FP & 4) && defined(__ARMEL__) && \
    !defined(ABBE_PORTABLE_C)
#define ABBE_M4F_ASM 1
#endif

#if defined(ABBE_M4F_ASM)
/* Cortex-M4F: the accumulators in s16-s21, so that one VLDM loads the
 * first row into them (GCC never combines VLDRs), and each further row is
 * one VLDM into s24-s29 (callee-saved like the accumulators: one
 * VPUSH saves them all, and s0-s15 stay free for the basis) and six fused multiply-adds: 7 instructions per
 * row instead of 12. Rows are 4-byte aligned (ABBE_E_ALIGN).
 * Macros: the six-term kernel and the rotary motions' one (below) declare
 * their accumulators with ACC6_DECL() and stream rows through `row`. */
#define ACC6_DECL()                                                                        \
    register float a0 __asm__("s16");                                                      \
    register float a1 __asm__("s17");                                                      \
    register float a2 __asm__("s18");                                                      \
    register float a3 __asm__("s19");                                                      \
    register float a4 __asm__("s20");                                                      \
    register float a5 __asm__("s21")
#define ZERO6() do { a0 = 0.0f; a1 = 0.0f; a2 = 0.0f; a3 = 0.0f; a4 = 0.0f; a5 = 0.0f; } while (0)
#define FIRST6()                                                                           \
    __asm__("vldmia %[p]!, {s16-s21}"                                                      \
            : "=t"(a0), "=t"(a1), "=t"(a2), "=t"(a3), "=t"(a4), "=t"(a5), [p] "+r"(row)     \
            : "m"(*(const struct { uint8_t bytes[24]; } *)row))
#define ROW6(bv_)                                                                            \
    __asm__("vldmia %[p]!, {s24-s29}\n\t"                                                 \
            "vfma.f32 %[a0], s24, %[bb]\n\t"                                                \
            "vfma.f32 %[a1], s25, %[bb]\n\t"                                                \
            "vfma.f32 %[a2], s26, %[bb]\n\t"                                                \
            "vfma.f32 %[a3], s27, %[bb]\n\t"                                                \
            "vfma.f32 %[a4], s28, %[bb]\n\t"                                                \
            "vfma.f32 %[a5], s29, %[bb]"                                                    \
            : [a0] "+t"(a0), [a1] "+t"(a1), [a2] "+t"(a2), [a3] "+t"(a3), [a4] "+t"(a4),   \
              [a5] "+t"(a5), [p] "+r"(row)                                                 \
            : [bb] "t"(bv_), "m"(*(const struct { uint8_t bytes[24]; } *)row)                \
            : "s24", "s25", "s26", "s27", "s28", "s29")
/* One row in the harmonics' asm below: b its basis value (an operand name). */
#define ROW6_ASM(b)                                                                        \
    "vldmia %[p]!, {s24-s29}\n\t"                                                          \
    "vfma.f32 %[a0], s24, " b "\n\t"                                                       \
    "vfma.f32 %[a1], s25, " b "\n\t"                                                       \
    "vfma.f32 %[a2], s26, " b "\n\t"                                                       \
    "vfma.f32 %[a3], s27, " b "\n\t"                                                       \
    "vfma.f32 %[a4], s28, " b "\n\t"                                                       \
    "vfma.f32 %[a5], s29, " b "\n\t"
/* A block's harmonics in one asm loop, two per pass: (s, c) and (t0, t1)
 * take turns as the current harmonic, so rotating to the next one is four
 * instructions and no register moves (GCC adds two moves per harmonic to
 * the same loop in C). The rows are read through p; the "m" operand names
 * the most they can span (8 harmonics x 2 rows x 24 bytes). */
#define HARM6(s1v, c1v, hv)                                                                \
    do {                                                                                   \
        float s_ = (s1v), c_ = (c1v), t0_, t1_;                                            \
        unsigned n_ = (hv);                                                                \
        __asm__(ROW6_ASM("%[s]") ROW6_ASM("%[c]")                                          \
                "1:\n\t"                                                                   \
                "subs %[n], %[n], #1\n\t"                                                  \
                "beq 2f\n\t"                                                               \
                "vmul.f32 %[t0], %[s], %[c1]\n\t"                                          \
                "vfma.f32 %[t0], %[c], %[s1]\n\t"                                          \
                "vmul.f32 %[t1], %[c], %[c1]\n\t"                                          \
                "vfms.f32 %[t1], %[s], %[s1]\n\t"                                          \
                ROW6_ASM("%[t0]") ROW6_ASM("%[t1]")                                        \
                "subs %[n], %[n], #1\n\t"                                                  \
                "beq 2f\n\t"                                                               \
                "vmul.f32 %[s], %[t0], %[c1]\n\t"                                          \
                "vfma.f32 %[s], %[t1], %[s1]\n\t"                                          \
                "vmul.f32 %[c], %[t1], %[c1]\n\t"                                          \
                "vfms.f32 %[c], %[t0], %[s1]\n\t"                                          \
                ROW6_ASM("%[s]") ROW6_ASM("%[c]")                                          \
                "b 1b\n"                                                                   \
                "2:"                                                                       \
                : [a0] "+t"(a0), [a1] "+t"(a1), [a2] "+t"(a2), [a3] "+t"(a3), [a4] "+t"(a4), \
                  [a5] "+t"(a5), [p] "+r"(row), [n] "+r"(n_), [s] "+&t"(s_), [c] "+&t"(c_),  \
                  [t0] "=&t"(t0_), [t1] "=&t"(t1_)                                          \
                : [s1] "t"(s1v), [c1] "t"(c1v),                                            \
                  "m"(*(const struct { uint8_t bytes[ABBE_MAX_HARMONICS * 48]; } *)row)      \
                : "s24", "s25", "s26", "s27", "s28", "s29", "cc");                         \
    } while (0)
#else
#define ACC6_DECL() float a0, a1, a2, a3, a4, a5
#define ZERO6() do { a0 = 0.0f; a1 = 0.0f; a2 = 0.0f; a3 = 0.0f; a4 = 0.0f; a5 = 0.0f; } while (0)
#define FIRST6() \
    do { a0 = LD(0); a1 = LD(1); a2 = LD(2); a3 = LD(3); a4 = LD(4); a5 = LD(5); row += 24; } while (0)
#define ROW6(b)                                                                            \
    do {                                                                                   \
        const float b_ = (b);                                                              \
        a0 += LD(0) * b_; a1 += LD(1) * b_; a2 += LD(2) * b_;                              \
        a3 += LD(3) * b_; a4 += LD(4) * b_; a5 += LD(5) * b_;                              \
        row += 24;                                                                         \
    } while (0)
#endif
#if !defined(ABBE_M4F_ASM)
#define HARM6(s1v, c1v, hv) ABBE_HARMONICS_C(ROW6, s1v, c1v, hv)
#endif

#if !defined(ABBE_F32_SSE2)



/* A fitted axis: six columns, the accumulators in registers, folded into e
 * at once (the values never go through memory). w: NULL (a compile-time
 * constant: the 3-axis kernel below), or the five-axis evaluation's sum of
 * the axes' angles, which gets wsign x (eps_x, eps_y, eps_z) from the same
 * accumulators (one pass of the basis for both). */
static ABBE_ALWAYS_INLINE abbe_vec3f_t fold6_body(const abbe_axis_model_t *ax, uint32_t d, float ex, float ey,
                                                  float ez, float rx, float ry, float rz, float lin, float *w,
                                                  float wsign)
{
    /* scalars, not the two aggregates: GCC stores an aggregate argument to
     * the stack on entry, even where it then uses the registers */
    abbe_vec3f_t e = {ex, ey, ez};
    const abbe_vec3f_t r = {rx, ry, rz};
    const uint8_t *row = ax->coef_f32;
    ACC6_DECL();
    ABBE_BASIS_F32(ax, d, ZERO6, FIRST6, ROW6, HARM6);
    ABBE_FOLD6(e, r, lin, a0, a1, a2, a3, a4, a5);
    if (w != NULL) {
        w[0] += wsign * a3;
        w[1] += wsign * a4;
        w[2] += wsign * a5;
    }
    return e;
}

#endif /* !ABBE_F32_SSE2 */

#endif /* ABBE_KERNEL_F32_H */
