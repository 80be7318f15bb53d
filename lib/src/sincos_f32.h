/* abbe: sin and cos of a phase in single precision, inline for the per-axis
 * kernels (terms_f32.c); sincos_f32.c exports the same for the tests.
 *
 * The phase stays an integer fraction of a turn, so the reduction is exact
 * and only the polynomials and the rotation round (max error about 1.1e-7,
 * two float ulp; docs/numerics.md). Branch-free. */
#ifndef ABBE_SINCOS_F32_H
#define ABBE_SINCOS_F32_H

#include "internal.h"

/* The polynomials' coefficients (in the order the Horner steps use them,
 * then 1), and sin and cos of the eighths of a turn, k pi/4, as (sin, cos)
 * pairs, the irrational ones sqrt(1/2) correctly rounded. One block: a
 * Cortex-M4F loads the seven constants with one VLDM. */
typedef struct {
    float poly[8]; /* S2, S1, S0, C3, C2, C1, 1, (0) */
    float eighth[16];
} abbe_sincos_f32_table_t;

/* One table for the whole library (sincos_f32.c): the kernels that inline
 * the sin/cos (terms_f32.c, terms_rot_f32.c, sincos_f32.c) read the same 96 B
 * (a static copy per translation unit cost a five-axis image 192 B of flash,
 * bench/results.md section 11; the address is one literal either way). */
extern const abbe_sincos_f32_table_t abbe_sincos_f32_table;

/* The phase is reduced to the nearest eighth of a turn k (exact, integer),
 * leaving r in [-1/16, 1/16) turn, u = r / 2^29 in [-1/2, 1/2) and the angle
 * pi/4 u: sin(pi/4 u) = u (S0 + S1 z + S2 z^2) and cos(pi/4 u) = 1 + C1 z +
 * C2 z^2 + C3 z^3, z = u^2 (near-minimax, docs/numerics.md), then rotated
 * by k pi/4 from the table: two multiplies and two multiply-adds, where a
 * quarter-turn reduction needs longer polynomials and a swap and two
 * negations chosen by the quarter. No branch either way. */
static ABBE_ALWAYS_INLINE void abbe_sincos_f32_inline(uint32_t phase_q32, float *sin_out, float *cos_out)
{
    const uint32_t eighth = (phase_q32 + 0x10000000u) >> 29;           /* 0..7 (wraps) */
    const int32_t r = abbe_u32_to_i32(phase_q32 - (eighth << 29));    /* [-2^28, 2^28) */
    const abbe_sincos_f32_table_t *k = &abbe_sincos_f32_table;
#if defined(__GNUC__) && defined(__thumb2__) && defined(__ARM_FP) && defined(__ARMEL__) && !defined(ABBE_PORTABLE_C)
    /* Cortex-M4F: the same operations in the same order, in one asm block:
     * GCC hoists the seven constants out of a kernel's block loop into
     * registers and then copies each into place (a Horner step overwrites its
     * addend), where one VLDM per evaluation does it; VCVT with 29 fraction
     * bits is the scaling. The VMOV of the integer into the FPU register is
     * in the asm: an int input tied to the float output ("0"(r)) is what GCC
     * accepts but LLVM rejects ("matching output constraint of incompatible
     * type"); GCC makes the same code of both (a copy of r's bits into a float
     * first, then "+t", costs GCC 4 B of flash through register allocation). */
    float u, z, so, co;
    uint32_t row;
    __asm__("vmov %[u], %[r]\n\t"
            "vcvt.f32.s32 %[u], %[u], #29"
            : [u] "=t"(u)
            : [r] "r"(r));
    __asm__("vldmia %[k], {s8-s14}\n\t"
            "vmul.f32 %[z], %[u], %[u]\n\t"
            "vfma.f32 s9, %[z], s8\n\t"   /* S1 + z S2 */
            "vfma.f32 s10, %[z], s9\n\t"  /* S0 + z (..) */
            "vfma.f32 s12, %[z], s11\n\t" /* C2 + z C3 */
            "vfma.f32 s13, %[z], s12\n\t" /* C1 + z (..) */
            "vfma.f32 s14, %[z], s13\n\t" /* c = 1 + z (..) */
            "vmul.f32 s10, s10, %[u]\n\t" /* s */
            "add %[row], %[k], %[e], lsl #3\n\t"
            "vldr s8, [%[row], #32]\n\t"  /* sin k pi/4 */
            "vldr s9, [%[row], #36]\n\t"  /* cos k pi/4 */
            "vmul.f32 %[so], s10, s9\n\t"
            "vfma.f32 %[so], s14, s8\n\t" /* s ck + c sk */
            "vmul.f32 %[co], s14, s9\n\t"
            "vfms.f32 %[co], s10, s8"     /* c ck - s sk */
            : [so] "=&t"(so), [co] "=&t"(co), [z] "=&t"(z), [row] "=&r"(row)
            : [u] "t"(u), [k] "r"(k), [e] "r"(eighth), "m"(*k)
            : "s8", "s9", "s10", "s11", "s12", "s13", "s14");
    *sin_out = so;
    *cos_out = co;
#else
    const float u = (float)r * 1.86264514923095703125e-9f; /* r / 2^29 */
    const float z = u * u;
    const float *c = k->poly;
    const float s = u * (c[2] + z * (c[1] + z * c[0]));
    const float cs = 1.0f + z * (c[5] + z * (c[4] + z * c[3]));
    const float sk = k->eighth[2u * eighth], ck = k->eighth[2u * eighth + 1u];
    *sin_out = s * ck + cs * sk;
    *cos_out = cs * ck - s * sk;
#endif
}

#endif /* ABBE_SINCOS_F32_H */
