/* abbe: argument reduction in integers, shared by both numeric variants.
 *
 * Positions are integer nm in both variants, so the Chebyshev argument and the
 * Fourier phase are computed exactly the same way, to about 1 LSB, whatever the
 * distance from the origin (docs/numerics.md). A float phase would lose
 * 2^-24 of up to 4000 turns, i.e. degrees on a short-period harmonic.
 */
#include "internal.h"

int32_t abbe_arg_clamp(const abbe_axis_model_t *ax, int32_t pos_nm, uint32_t *flags)
{
    if (pos_nm < ax->travel_min_nm) {
        *flags |= ABBE_FLAG_OUT_OF_TRAVEL;
        return ax->travel_min_nm;
    }
    if (pos_nm > ax->travel_max_nm) {
        *flags |= ABBE_FLAG_OUT_OF_TRAVEL;
        return ax->travel_max_nm;
    }
    return pos_nm;
}

int32_t abbe_arg_cheb_q30(const abbe_axis_model_t *ax, int32_t clamped_nm)
{
    /* |num| <= span < 2^32 and cheb_mul ~ 2^62 / span: the product stays within 2^62. */
    int64_t num = 2 * (int64_t)clamped_nm - (int64_t)ax->travel_min_nm - (int64_t)ax->travel_max_nm;
    int64_t u = abbe_shr_round(num * ax->cheb_mul, ax->cheb_shift);
    return (int32_t)abbe_clamp_i64(u, -ABBE_Q30_ONE, ABBE_Q30_ONE);
}

uint32_t abbe_arg_phase_q32(const abbe_axis_model_t *ax, unsigned block, int32_t clamped_nm)
{
    /* freq = 2^64 / period. Bits 32..63 of d * freq are the phase in Q32; the
     * unsigned product wraps mod 2^64, which drops exactly the whole turns. */
    int64_t d = (int64_t)clamped_nm - (int64_t)ax->origin_nm[block];
    uint64_t product = (uint64_t)d * ax->freq[block];
    return (uint32_t)(product >> 32);
}

int32_t abbe_arg_takeup_q30(const abbe_axis_model_t *ax, uint32_t dist_nm)
{
    /* Crossing the whole take-up flips the state from -1 to +1: 2^31 in Q30. */
    if ((int64_t)dist_nm >= (int64_t)ax->backlash_takeup_nm) {
        return INT32_MAX;
    }
    uint64_t ds = ((uint64_t)dist_nm * ax->takeup_rate_q46) >> 15; /* dist < takeup: < 2^31 */
    return (int32_t)(ds > (uint64_t)INT32_MAX ? (uint64_t)INT32_MAX : ds);
}
