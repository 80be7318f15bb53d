/* abbe: sin and cos of a phase in Q30, integer only.
 *
 * The phase (fraction of a turn, Q32) is reduced to the nearest quarter turn,
 * leaving r in [-1/8, 1/8) turn; sin and cos of r come from near-minimax
 * polynomials in u = 8r (|u| <= 1), and the quarter index rotates them.
 * Max error 3.0e-9 (about 3 LSB), measured over 50 000 phases against float64
 * (docs/numerics.md). The same coefficients serve sincos_f32.c.
 */
#include "internal.h"

/* sin(pi/4 u) = u * S(u^2), cos(pi/4 u) = C(u^2), coefficients in Q30. */
static const int32_t sin_q30[4] = {843314847, -86699691, 2673504, -38536};
static const int32_t cos_q30[5] = {1073741824, -331168968, 17023455, -349979, 3792};

static int32_t mul_q30(int32_t a, int32_t b)
{
    return (int32_t)abbe_shr_round((int64_t)a * b, 30u);
}

void abbe_sincos_q30(uint32_t phase_q32, int32_t *sin_out, int32_t *cos_out)
{
    uint32_t quarter = ((phase_q32 + (1u << 29)) >> 30) & 3u;
    int32_t r = abbe_u32_to_i32(phase_q32 - (quarter << 30)); /* [-2^29, 2^29) */
    int32_t u_q31 = r * 4;                                    /* u = r / 2^29 in Q31 */
    int32_t z_q30 = (int32_t)(((int64_t)u_q31 * u_q31) >> 32);

    int32_t ps = sin_q30[3];
    ps = sin_q30[2] + mul_q30(ps, z_q30);
    ps = sin_q30[1] + mul_q30(ps, z_q30);
    ps = sin_q30[0] + mul_q30(ps, z_q30);
    int32_t s = (int32_t)abbe_shr_round((int64_t)u_q31 * ps, 31u);

    int32_t c = cos_q30[4];
    c = cos_q30[3] + mul_q30(c, z_q30);
    c = cos_q30[2] + mul_q30(c, z_q30);
    c = cos_q30[1] + mul_q30(c, z_q30);
    c = cos_q30[0] + mul_q30(c, z_q30);

    switch (quarter) {
    case 0: *sin_out = s; *cos_out = c; break;
    case 1: *sin_out = c; *cos_out = -s; break;
    case 2: *sin_out = -s; *cos_out = -c; break;
    default: *sin_out = -c; *cos_out = s; break;
    }
}
