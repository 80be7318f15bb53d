/* abbe: sin and cos of a phase in single precision, inline for the per-axis
 * kernels (terms_f32.c); sincos_f32.c exports the same for the tests.
 *
 * Same reduction and polynomials as sincos_q.c: the phase stays an integer
 * fraction of a turn, so reduction is exact and only the polynomial rounds
 * (max error about 1.5e-7, a few float ulp; docs/numerics.md). Branch-free:
 * the quarter turn selects and negates with conditional moves. */
#ifndef ABBE_SINCOS_F32_H
#define ABBE_SINCOS_F32_H

#include "internal.h"

/* A float constant materialised where it is used. In a kernel's block loop
 * GCC would otherwise hoist all nine polynomial constants into callee-saved
 * registers (nine loads, a save and a restore per axis on the Cortex-M4F)
 * and still copy each into place: a Horner step costs one load or move plus
 * one multiply-add either way. */
#if defined(__GNUC__) && defined(__thumb2__) && defined(__ARM_FP) && !defined(ABBE_PORTABLE_C)
#define ABBE_K(name, value) float name = (value); __asm__("" : "+t"(name))
#else
#define ABBE_K(name, value) const float name = (value)
#endif

static ABBE_ALWAYS_INLINE void abbe_sincos_f32_inline(uint32_t phase_q32, float *sin_out, float *cos_out)
{
    uint32_t quarter = ((phase_q32 + (1u << 29)) >> 30) & 3u;
    int32_t r = abbe_u32_to_i32(phase_q32 - (quarter << 30)); /* [-2^29, 2^29) */
    float u = (float)r * 1.86264514923095703125e-9f;          /* r / 2^29 */
    float z = u * u;

    ABBE_K(s3, -3.588928186218254e-05f);
    ABBE_K(s2, 0.0024898941721767187f);
    ABBE_K(s1, -0.08074537664651871f);
    ABBE_K(s0, 0.7853981256484985f);
    float s = u * (s0 + z * (s1 + z * (s2 + z * s3)));
    ABBE_K(c4, 3.5318628215463832e-06f);
    ABBE_K(c3, -0.00032594305230304599f);
    ABBE_K(c2, 0.015854328870773315f);
    ABBE_K(c1, -0.30842512845993042f);
    float c = 1.0f + z * (c1 + z * (c2 + z * (c3 + z * c4)));

    /* quarter 0: (s, c), 1: (c, -s), 2: (-s, -c), 3: (-c, s) */
    float sw = (quarter & 1u) ? c : s;
    float cw = (quarter & 1u) ? s : c;
    *sin_out = (quarter & 2u) ? -sw : sw;
    *cos_out = ((quarter + 1u) & 2u) ? -cw : cw;
}

#endif /* ABBE_SINCOS_F32_H */
