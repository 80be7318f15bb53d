/* abbe: sin and cos of a phase in single precision.
 *
 * Same reduction and polynomials as sincos_q.c: the phase stays an integer
 * fraction of a turn, so reduction is exact and only the polynomial rounds
 * (max error about 1.5e-7, a few float ulp; docs/numerics.md).
 */
#include "internal.h"

void abbe_sincos_f32(uint32_t phase_q32, float *sin_out, float *cos_out)
{
    uint32_t quarter = ((phase_q32 + (1u << 29)) >> 30) & 3u;
    int32_t r = abbe_u32_to_i32(phase_q32 - (quarter << 30)); /* [-2^29, 2^29) */
    float u = (float)r * 1.86264514923095703125e-9f;          /* r / 2^29 */
    float z = u * u;

    float s = u * (0.7853981256484985f +
                   z * (-0.08074537664651871f +
                        z * (0.0024898941721767187f + z * -3.588928186218254e-05f)));
    float c = 1.0f +
              z * (-0.30842512845993042f +
                   z * (0.015854328870773315f +
                        z * (-0.00032594305230304599f + z * 3.5318628215463832e-06f)));

    switch (quarter) {
    case 0: *sin_out = s; *cos_out = c; break;
    case 1: *sin_out = c; *cos_out = -s; break;
    case 2: *sin_out = -s; *cos_out = -c; break;
    default: *sin_out = -c; *cos_out = s; break;
    }
}
