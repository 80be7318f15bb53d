/* abbe: helpers shared by the library's source files. Not installed. */
#ifndef ABBE_INTERNAL_H
#define ABBE_INTERNAL_H

#include <stdint.h>
#include <string.h>

#include "abbe/abbe.h"

/* Fixed point relies on >> of a negative value being an arithmetic shift.
 * C99 leaves that to the implementation; every compiler we target does it. */
typedef char abbe_requires_arithmetic_shift[((-2 >> 1) == -1) ? 1 : -1];

#define ABBE_Q30_ONE ((int32_t)1 << 30)

/* Hot-path helpers that must be specialised per call site (constant column
 * count); plain inline elsewhere. */
#if defined(__GNUC__)
#define ABBE_ALWAYS_INLINE inline __attribute__((always_inline))
#else
#define ABBE_ALWAYS_INLINE inline
#endif

/* Little-endian loads; compilers turn these into one load on LE targets. */
static inline uint32_t abbe_ld_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) |
           ((uint32_t)p[3] << 24);
}

static inline uint16_t abbe_ld_u16(const uint8_t *p)
{
    return (uint16_t)((uint16_t)p[0] | (uint16_t)((uint16_t)p[1] << 8));
}

static inline int32_t abbe_ld_i32(const uint8_t *p)
{
    uint32_t u = abbe_ld_u32(p);
    int32_t v;
    memcpy(&v, &u, sizeof v); /* two's complement reinterpretation, no implementation-defined cast */
    return v;
}

static inline float abbe_ld_f32(const uint8_t *p)
{
    uint32_t u = abbe_ld_u32(p);
    float v;
    memcpy(&v, &u, sizeof v);
    return v;
}

/* A float32 coefficient at a 4-byte aligned address of a little-endian host:
 * one FPU load (vldr) instead of an integer load and a move. The loader has
 * checked the alignment (ABBE_E_ALIGN) and the offsets. */
#if (defined(__GNUC__) || defined(__clang__)) && defined(__BYTE_ORDER__) && \
    __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
static inline float abbe_ld_f32_aligned(const uint8_t *p)
{
    float v;
    memcpy(&v, __builtin_assume_aligned(p, 4), sizeof v);
    return v;
}
#else
#define abbe_ld_f32_aligned abbe_ld_f32
#endif

/* Two's complement uint32 -> int32 without an implementation-defined cast. */
static inline int32_t abbe_u32_to_i32(uint32_t u)
{
    int32_t v;
    memcpy(&v, &u, sizeof v);
    return v;
}

/* Round-half-up right shift of a signed value (n >= 1). Callers keep |v| < 2^62. */
static inline int64_t abbe_shr_round(int64_t v, unsigned n)
{
    return (v + ((int64_t)1 << (n - 1u))) >> n;
}

/* Saturate to int32, recording the event in *flags. */
static inline int32_t abbe_sat_i32(int64_t v, uint32_t *flags)
{
    if (v > INT32_MAX) {
        *flags |= ABBE_FLAG_SATURATED;
        return INT32_MAX;
    }
    if (v < INT32_MIN) {
        *flags |= ABBE_FLAG_SATURATED;
        return INT32_MIN;
    }
    return (int32_t)v;
}

static inline int64_t abbe_clamp_i64(int64_t v, int64_t lo, int64_t hi)
{
    return v < lo ? lo : (v > hi ? hi : v);
}

/* True for NaN and +/-Inf, by the IEEE bit pattern (no float compare). */
static inline int abbe_f32_bits_nonfinite(uint32_t bits)
{
    return (bits & 0x7F800000u) == 0x7F800000u;
}

static inline int abbe_f32_nonfinite(float f)
{
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    return abbe_f32_bits_nonfinite(u);
}

/* ---- argument reduction (integer, shared by both variants) ----
 *
 * Positions are integer nm in both variants, so the Chebyshev argument and the
 * Fourier phase are computed exactly the same way, to about 1 LSB, whatever the
 * distance from the origin (docs/numerics.md). A float phase would lose 2^-24
 * of up to 4000 turns, i.e. degrees on a short-period harmonic. Inline: they
 * run once per axis and block on the hot path. */

/* Position clamped to the axis travel; sets ABBE_FLAG_OUT_OF_TRAVEL if clamped. */
static inline int32_t abbe_arg_clamp(const abbe_axis_model_t *ax, int32_t pos_nm, uint32_t *flags)
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

/* Chebyshev argument u = (2p - min - max) / (max - min) in Q30, p clamped. */
static inline int32_t abbe_arg_cheb_q30(const abbe_axis_model_t *ax, int32_t clamped_nm)
{
    /* |num| <= span < 2^32 and cheb_mul ~ 2^62 / span: the product stays within 2^62. */
    int64_t num = 2 * (int64_t)clamped_nm - (int64_t)ax->travel_min_nm - (int64_t)ax->travel_max_nm;
    int64_t u = abbe_shr_round(num * ax->cheb_mul, 32u);
    return (int32_t)abbe_clamp_i64(u, -ABBE_Q30_ONE, ABBE_Q30_ONE);
}

/* Phase of Fourier block b as a fraction of a turn (Q32, wraps), p clamped. */
static inline uint32_t abbe_arg_phase_q32(const abbe_axis_model_t *ax, unsigned block, int32_t clamped_nm)
{
    /* freq = 2^64 / period. Bits 32..63 of d * freq are the phase in Q32; the
     * unsigned product wraps mod 2^64, which drops exactly the whole turns. */
    int64_t d = (int64_t)clamped_nm - (int64_t)ax->origin_nm[block];
    uint64_t product = (uint64_t)d * ax->freq[block];
    return (uint32_t)(product >> 32);
}

/* Backlash direction-state change (Q30) for a move of dist_nm >= 0. */
static inline int32_t abbe_arg_takeup_q30(const abbe_axis_model_t *ax, uint32_t dist_nm)
{
    /* Crossing the whole take-up flips the state from -1 to +1: 2^31 in Q30. */
    if ((int64_t)dist_nm >= (int64_t)ax->backlash_takeup_nm) {
        return INT32_MAX;
    }
    uint64_t ds = ((uint64_t)dist_nm * ax->takeup_rate_q46) >> 15; /* dist < takeup: < 2^31 */
    return (int32_t)(ds > (uint64_t)INT32_MAX ? (uint64_t)INT32_MAX : ds);
}

/* ---- sin/cos of a phase (fraction of a turn, Q32): sincos_q.c / sincos_f32.c ---- */
void abbe_sincos_q30(uint32_t phase_q32, int32_t *sin_q30, int32_t *cos_q30);
void abbe_sincos_f32(uint32_t phase_q32, float *sin_out, float *cos_out);

/* ---- per-axis fitted term values ---- */

/* Fixed: linear terms in 2^-8 nm, angular in 2^-36 rad; absent terms 0. */
void abbe_axis_terms_q(const abbe_axis_model_t *ax, int32_t pos_nm, int64_t *restrict value,
                       uint32_t *flags);

/* Float: linear terms in um, angular in urad; absent terms 0. */
void abbe_axis_terms_f32(const abbe_axis_model_t *ax, int32_t pos_nm, float *restrict value,
                         uint32_t *flags);

/* Float mm -> integer nm, exact to 0.56 nm over +/-2147 mm (docs/numerics.md).
 * Returns ABBE_E_INPUT for NaN/Inf; clamps beyond +/-2147 mm (flagging out of travel). */
abbe_status_t abbe_mm_to_nm_f32(float mm, int32_t *nm, uint32_t *flags);

#endif /* ABBE_INTERNAL_H */
