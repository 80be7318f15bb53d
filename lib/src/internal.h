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

/* The variants: both unless a build leaves one out with -DABBE_WITH_F32=0
 * (lib/CMakeLists.txt passes its ABBE_WITH_F32 option as 0 or 1). A build
 * without CMake (a vendor IDE, LinuxCNC's module makefile) compiles every
 * source and gets both: the loader must then prepare the float constants
 * the _f32 evaluation reads, so the default is "on", never "undefined". */
#ifndef ABBE_WITH_F32
#define ABBE_WITH_F32 1
#endif

/* SIMD kernels where the target guarantees them: SSE2 is part of every
 * x86-64. ABBE_PORTABLE_C forces the plain C kernels everywhere (the
 * sanitizer build uses it, so both versions are tested on the host). */
#if defined(__SSE2__) && !defined(ABBE_PORTABLE_C) && ABBE_WITH_F32
#define ABBE_F32_SSE2 1
#endif
/* The model's four-lane copies (model.h) are built only for those kernels. */
#if defined(ABBE_F32_SSE2)
#define ABBE_X86_LANES 1
#endif

#if defined(__GNUC__)
#define ABBE_NOINLINE __attribute__((noinline))
#else
#define ABBE_NOINLINE
#endif

/* Out of line and off the hot path: a function only the rare branch calls (a
 * saturation), so the compiler lays the common path out straight. */
#if defined(__GNUC__)
#define ABBE_COLD __attribute__((noinline, cold))
#else
#define ABBE_COLD
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
/* The same for an int32 coefficient (the _q kernels' reads): one load, which
 * is also what GCC makes of abbe_ld_i32's four bytes here. Written as one
 * load of the word so that the proof of the evaluation for any coefficients
 * (docs/proofs.md) reads the word's value: an interval analysis loses a
 * signed value's range when it is rebuilt from its bytes. */
static inline int32_t abbe_ld_i32_aligned(const uint8_t *p)
{
    int32_t v;
    memcpy(&v, p, sizeof v);
    return v;
}
#else
#define abbe_ld_f32_aligned abbe_ld_f32
#define abbe_ld_i32_aligned abbe_ld_i32
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

/* True for NaN, +/-Inf and |t| > 10^6 degC, by the magnitude's bit pattern
 * (IEEE magnitudes order as their bits; 0x49742400 is 10^6 exactly): a
 * temperature no sensor reports, refused like NaN so that alpha * dT stays
 * finite (the _q variant clamps dT to 2^30 mK). */
static inline int abbe_f32_temp_invalid(float t)
{
    uint32_t u;
    memcpy(&u, &t, sizeof u);
    return (u & 0x7FFFFFFFu) > 0x49742400u;
}

/* acc + a * b, 64-bit: one SMLAL on a Cortex-M3/M4. GCC keeps the plain C
 * form as one SMLAL in the dot products, but not where acc is made of
 * constants (the Horner steps of sincos_q.c), which it rebuilds as a 64 x 64
 * multiply of 7 instructions; the asm pins the single instruction there. */
static ABBE_ALWAYS_INLINE int64_t abbe_smlal(int64_t acc, int32_t a, int32_t b)
{
#if defined(__GNUC__) && defined(__thumb2__) && defined(__ARMEL__) && !defined(ABBE_PORTABLE_C)
    uint32_t lo = (uint32_t)acc, hi = (uint32_t)((uint64_t)acc >> 32);
    __asm__("smlal %0, %1, %2, %3" : "+r"(lo), "+r"(hi) : "r"(a), "r"(b));
    return (int64_t)(((uint64_t)hi << 32) | lo);
#else
    return acc + (int64_t)a * b;
#endif
}

/* ---- argument reduction (integer, shared by both variants) ----
 *
 * Positions are integer nm in both variants, so clamping, the Chebyshev
 * argument and the Fourier phases are computed exactly the same way, to about
 * 1 LSB, whatever the distance from the origin (docs/numerics.md). A float
 * phase would lose 2^-24 of up to 4000 turns, i.e. degrees on a short-period
 * harmonic. Everything starts from one offset per axis, d = p - travel_min
 * with p clamped to the travel: 0 <= d <= span < 2^32, so it is a uint32 and
 * every product below is a single 32 x 32 -> 64 multiply (one UMULL/UMLAL on
 * a Cortex-M). Inline: they run once per axis on the hot path. */

/* Offset of the clamped position from travel_min, in [0, span]; sets
 * ABBE_FLAG_OUT_OF_TRAVEL if pos_nm is outside the travel. Branch-free. */
static inline uint32_t abbe_arg_offset(const abbe_axis_model_t *ax, int32_t pos_nm, uint32_t *flags)
{
    /* clamp, then one compare for the flag: two conditional moves on ARM */
    int32_t c = pos_nm < ax->travel_min_nm ? ax->travel_min_nm : pos_nm;
    c = c > ax->travel_max_nm ? ax->travel_max_nm : c;
    *flags |= (uint32_t)(c != pos_nm) * ABBE_FLAG_OUT_OF_TRAVEL;
    return (uint32_t)c - (uint32_t)ax->travel_min_nm; /* in [0, span]: exact mod 2^32 */
}

/* Position clamped to the axis travel; sets ABBE_FLAG_OUT_OF_TRAVEL if clamped. */
static inline int32_t abbe_arg_clamp(const abbe_axis_model_t *ax, int32_t pos_nm, uint32_t *flags)
{
    uint32_t d = abbe_arg_offset(ax, pos_nm, flags);
    return abbe_u32_to_i32((uint32_t)ax->travel_min_nm + d);
}

/* Chebyshev argument u = (2p - min - max) / (max - min) = 2d / span - 1 in
 * Q30, from the offset d. (d << shift) < 2^32 and cheb_mul = round(2^(63 -
 * shift) / span) < 2^32 (the loader picks shift), so hi32 of their product is
 * d * 2^31 / span to within 0.5 LSB, and the + 2^31 rounds: within 1 LSB in
 * all. (A power-of-two span, whose exact multiplier 2^32 is stored as
 * 2^32 - 1, comes out exact: there d << shift <= 2^31.) Range
 * [-2^30, 2^30]. */
static inline int32_t abbe_arg_cheb_q30(const abbe_axis_model_t *ax, uint32_t d)
{
    uint64_t prod = (uint64_t)(d << ax->cheb_shift) * ax->cheb_mul + 0x80000000u;
    return abbe_u32_to_i32((uint32_t)(prod >> 32) - (uint32_t)ABBE_Q30_ONE);
}

/* Phase of Fourier block b as a fraction of a turn (Q32, wraps), from the
 * offset d: bits 32..63 of (p - origin) * freq mod 2^64, with freq = round(2^64
 * / period). (p - origin) * freq = d * freq + (min - origin) * freq; the loader
 * stores the second product mod 2^64 (phase_min), and the unsigned arithmetic
 * wraps mod 2^64, which drops exactly the whole turns. d * freq mod 2^64 needs
 * only d * freq_lo (64 bits, added to phase_min) and the low word of
 * d * freq_hi. */
static inline uint32_t abbe_arg_phase_q32(const abbe_axis_model_t *ax, unsigned block, uint32_t d)
{
#if UINTPTR_MAX > 0xFFFFFFFFu
    /* 64-bit targets: the product mod 2^64 is one multiply */
    return (uint32_t)(((uint64_t)d * ax->freq[block] + ax->phase_min[block]) >> 32);
#else
    uint64_t freq = ax->freq[block];
    uint64_t low = (uint64_t)d * (uint32_t)freq + ax->phase_min[block];
    return (uint32_t)(low >> 32) + d * (uint32_t)(freq >> 32);
#endif
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
/* The same pair as one value: sin's bits in the low word, cos's in the high. */
uint64_t abbe_sincos_q30_pair(uint32_t phase_q32);
void abbe_sincos_f32(uint32_t phase_q32, float *sin_out, float *cos_out);

/* sin or cos of a phase as abbe_sincos_q30_pair packs it: its bits as an
 * int32 (the kernels' basis_q.h, abbe_sincos_q30). |value| <= 2^30 for every
 * phase: tests/proofs/hypotheses.c checks all 2^32 phases (the Eva proofs use it as a hypothesis, docs/proofs.md: an
 * interval analysis cannot follow the value through the packing). */
static ABBE_ALWAYS_INLINE int32_t abbe_q30_of_bits(uint32_t bits)
{
    const int32_t v = abbe_u32_to_i32(bits);
    /*@ assert sincos_range: -1073741824 <= v <= 1073741824; */
    return v;
}

/* ---- per-axis fitted term values (terms_q.c / terms_f32.c) ----
 *
 * From the offset d of abbe_arg_offset(); absent terms are 0.
 *   _q:   linear terms in 2^-6 nm (ABBE_TERM_LIN_Q_BITS), angular in 2^-35 rad
 *         (ABBE_TERM_ANG_Q_BITS), each rounded once from the exact int64 sum;
 *   _f32: in the coefficients' own units, 2^-8 nm and 2^-36 rad (the caller
 *         scales once, in the assembly). */
#define ABBE_TERM_LIN_Q_BITS 6
#define ABBE_TERM_ANG_Q_BITS 35
void abbe_axis_terms_q(const abbe_axis_model_t *ax, uint32_t d, int32_t value[ABBE_TERMS]);
/* The same for an axis with fewer than six terms (terms_sparse_q.c). */
void abbe_axis_terms_sparse_q(const abbe_axis_model_t *ax, uint32_t d, int32_t value[ABBE_TERMS]);
void abbe_axis_terms_f32(const abbe_axis_model_t *ax, uint32_t d, float value[ABBE_TERMS]);
/* The same for an axis with fewer than six terms (terms_f32.c). */
void abbe_axis_terms_sparse_f32(const abbe_axis_model_t *ax, uint32_t d, float value[ABBE_TERMS]);

/* Three floats: a homogeneous aggregate, returned in s0-s2 on a Cortex-M4F
 * (and e, r, lin go in s0-s6 as scalars: GCC stores an aggregate argument to
 * the stack on entry): no memory between the kernels. */
typedef struct {
    float x, y, z;
} abbe_vec3f_t;

/* e + an axis' share of Eq. 3 at its offset d: e + lin [d_x, d_y, d_z] +
 * [eps_x, eps_y, eps_z] x r, r the axis' lever arm, in the units of e over
 * the coefficients' (terms_f32.c; the plain C build, not x86-64's kernels). */
abbe_vec3f_t abbe_axis_fold_f32(const abbe_axis_model_t *ax, uint32_t d, float ex, float ey, float ez, float rx,
                                float ry, float rz, float lin);
/* A rotary axis' six error motions: the sums over k = 1..h (h >= 1) of its
 * rows (six sin(k t), six cos(k t) values), (s1, c1) = (sin t, cos t), the
 * three linear ones times lin, the angular ones times ang (terms_rot_f32.c,
 * the Fourier blocks' loop). */
void abbe_rotary_motions6_f32(const uint8_t *row, unsigned h, float s1, float c1, float lin, float ang, float m[6]);
/* The same (every build, x86-64 included) on e in place (e += the axis'
 * share), also adding wsign x (eps_x, eps_y, eps_z) to w: the five-axis
 * evaluation's one pass over an axis (terms_rot_f32.c). e and w in memory
 * rather than a returned abbe_vec3f_t: less stack (bench/results.md, section 11). */
void abbe_axis_fold_rot_f32(const abbe_axis_model_t *ax, uint32_t d, float e[3], float w[3], float wsign, float rx,
                            float ry, float rz, float lin);


/* Float mm -> integer nm, exact to 0.56 nm over +/-2147 mm (docs/numerics.md).
 * Returns ABBE_E_INPUT for NaN/Inf; clamps beyond +/-2147 mm (flagging out of travel). */
abbe_status_t abbe_mm_to_nm_f32(float mm, int32_t *nm, uint32_t *flags);

/* The same, inline and branch-free for the evaluation: returns nonzero for
 * NaN/Inf (then *nm is meaningless; the out-of-travel flag may be set).
 * The magnitude tests use the IEEE bits (a NaN is clamped like an infinity,
 * so nothing undefined is ever converted); the position is split into whole
 * millimetres (exact) and a fraction (exact, |f| < 1) whose product with 1e6
 * rounds by at most 0.06 nm, where mm * 1e6 would lose 64 nm; adding
 * 1.5 * 2^23 then rounds that product to the nearest integer (ties to even)
 * in the float unit itself, |f * 1e6| < 2^22 being far inside the range
 * where this is exact. */
/* The bits of a float clamped to +/-2147.0f (NaN and Inf to 2147.0f with
 * their sign): the bits of a finite float in [-2147, 2147] for every one of
 * the 2^32 inputs. tests/proofs/hypotheses.c checks them all (the Eva proofs
 * use it as the hypothesis 'mm_clamped': an interval analysis does not follow
 * a float through its bits). */
static ABBE_ALWAYS_INLINE uint32_t abbe_mm_clamp_bits(uint32_t bits)
{
    /* |mm| > 2147.0f, NaN and Inf included */
    return (bits & 0x7FFFFFFFu) > 0x45063000u ? ((bits & 0x80000000u) | 0x45063000u) : bits;
}

static ABBE_ALWAYS_INLINE uint32_t abbe_mm_to_nm_inline(float mm, int32_t *nm, uint32_t *flags)
{
    uint32_t bits;
    memcpy(&bits, &mm, sizeof bits);
    const uint32_t mag = bits & 0x7FFFFFFFu;
    const uint32_t over = (uint32_t)(mag > 0x45063000u); /* |mm| > 2147.0f, NaN and Inf included */
    *flags |= over * ABBE_FLAG_OUT_OF_TRAVEL;
    bits = abbe_mm_clamp_bits(bits);
    memcpy(&mm, &bits, sizeof mm);
    /*@ assert mm_clamped: \is_finite(mm) && -2147.0f <= mm <= 2147.0f; */
    const int32_t whole = (int32_t)mm;
    const float rounded = (mm - (float)whole) * 1.0e6f + 12582912.0f;
    uint32_t rounded_bits;
    memcpy(&rounded_bits, &rounded, sizeof rounded_bits);
    *nm = abbe_u32_to_i32((uint32_t)whole * 1000000u + (rounded_bits - 0x4B400000u));
    return (uint32_t)(mag >= 0x7F800000u);
}

/* ---- evaluation cores, shared by the public entry points, the batch calls and
 * the compensator (which passes its own direction states without copying) ---- */

/* Spatial error in nm (rounded, saturated) at pos_nm; returns the flags.
 * values: working memory for the 18 term values (the compensator passes its
 * scratch, so its cycle's stack stays small). */
uint32_t abbe_eval_q_core(const abbe_model_t *m, const int32_t pos_nm[ABBE_AXES],
                          const int32_t dir_q30[ABBE_AXES], const int32_t temp_mdegc[ABBE_AXES],
                          int32_t values[ABBE_AXES * ABBE_TERMS], int32_t error_nm[ABBE_AXES]);

/* The backlash and thermal terms (features BACKLASH, THERMAL), added to the
 * own positioning terms in error_um; lev_mm: p - ref per axis, mm; d: the
 * axis offsets of abbe_arg_offset(), the argument of the reversal blocks
 * (format 1.1; a library built without them has no such parameter). */
void abbe_f32_add_extras(const abbe_model_t *m, const float lev_mm[ABBE_AXES],
#if !defined(ABBE_NO_REVERSAL)
                         const uint32_t d[ABBE_AXES],
#endif
                         const float dir_state[ABBE_AXES], const float temp_c[ABBE_AXES], float error_um[ABBE_AXES]);

/* Nonzero if a direction state (BACKLASH) or temperature (THERMAL) is NaN/Inf. */
int abbe_f32_extras_nonfinite(uint32_t features, const float dir_state[ABBE_AXES], const float temp_c[ABBE_AXES]);

/* x86-64 builds also compile the f32 core for x86-64-v3 (ABBE_X86_V3, set by
 * lib/CMakeLists.txt for GCC and Clang); abbe_model_load() records in
 * model->simd which one this CPU runs. */
#define ABBE_SIMD_X86_V3 1u
#if defined(ABBE_X86_V3)
uint8_t abbe_simd_level(void);
abbe_status_t abbe_eval_f32_core_avx2(const abbe_model_t *m, const abbe_input_f32_t *in, abbe_error_f32_t *out);
#endif

/* Spatial error in um at the float input, with its flags, into *out; ABBE_OK,
 * or ABBE_E_INPUT (NaN/Inf input: then *out is all zero). m, in and out are
 * not NULL. Three pointers: all in registers, and abbe_error_eval_f32 is
 * a tail call. */
abbe_status_t abbe_eval_f32_core(const abbe_model_t *m, const abbe_input_f32_t *in, abbe_error_f32_t *out);

/* ---- five-axis tables (format 1.2, five_load.c) ---- */

/* The rotary section (header + tilt and table axis records) follows the three
 * linear axis records; coefficient arrays start after it. */
/* The newest minor the five-axis loader reads: 1.4 (kinds 3-5) unless built
 * without them (ABBE_NO_FIVE_KINDS: 1.2, a trunnion-only image). */
#if defined(ABBE_NO_FIVE_KINDS)
#define ABBE_FIVE_FORMAT_MINOR 2u
#else
#define ABBE_FIVE_FORMAT_MINOR 4u
#endif
#define ABBE_ROTARY_HEADER_OFFSET 256u
#define ABBE_ROTARY_HEADER_SIZE 64u
#define ABBE_ROTARY_RECORD_SIZE 64u
#define ABBE_ROTARY_DATA_START (ABBE_ROTARY_HEADER_OFFSET + ABBE_ROTARY_HEADER_SIZE + 2u * ABBE_ROTARY_RECORD_SIZE)

/* The kinds this library reads (abbe/five_axis.h ABBE_FIVE_KIND_MASK): the trunnions
 * (1, 2), and the chain kinds (3-5). */
#define ABBE_FIVE_TRUNNIONS_BUILT (((unsigned)(ABBE_FIVE_KIND_MASK) & 0x06u) != 0u)
#define ABBE_FIVE_CHAIN_MASK ((unsigned)(ABBE_FIVE_KIND_MASK) & 0x38u)

/* A chain model's kind (3-5, the loader refuses the kinds not built): a constant where the
 * library reads one chain kind only, so that the evaluation keeps that kind's geometry only. */
static inline unsigned abbe_five_chain_kind(const abbe_five_model_t *m5)
{
    return ABBE_FIVE_CHAIN_MASK == 0x08u   ? ABBE_KIN_XYZBC_HH
           : ABBE_FIVE_CHAIN_MASK == 0x10u ? ABBE_KIN_XYZBC_HT
           : ABBE_FIVE_CHAIN_MASK == 0x20u ? ABBE_KIN_XYZAB_TDR
                                           : (unsigned)m5->kind;
}

/* Phase (Q32 turn) of a rotary angle in micro-degrees: the angle modulo one
 * turn (360 000 000 udeg, exact in integers, so a full turn is an exact
 * period) times round(2^60 / 360e6) = 3202559735, >> 28 rounded (phase error
 * below 2^-31 turn). */
static inline uint32_t abbe_udeg_phase_q32(int32_t udeg)
{
    int32_t r = udeg % 360000000;
    r += r < 0 ? 360000000 : 0;
    return (uint32_t)(((uint64_t)(uint32_t)r * 3202559735u + (1u << 27)) >> 28);
}

/* Five-axis error, fixed point (five_eval_q.c), for the public call and the
 * compensator: values (18) is working memory, as for abbe_eval_q_core. */
uint32_t abbe_five_eval_q_core(const abbe_five_model_t *m5, const int32_t pos_nm[3], const int32_t angle_udeg[2],
                               const int32_t dir_q30[3], const int32_t temp_mdegc[3],
                               int32_t values[ABBE_AXES * ABBE_TERMS], int32_t error_nm[3], int32_t orient_nrad[3]);

/* Five-axis error, single precision (five_eval_f32.c), for the public call
 * and the compensator (which passes its arrays without copying), in two
 * calls one after the other: the linear axes' frames and the rotary axes'
 * are then never on the stack together (bench/results.md section 11).
 * abbe_five_eval_f32_linear: m the linear axes; *out their error, orientation
 * and flags, at the positions (nm, at[0..2]) then the angles (micro-degrees,
 * at[3..4]): one array, one argument fewer on the caller's stack; ABBE_OK,
 * or ABBE_E_INPUT (NaN/Inf: *out zero). After ABBE_OK,
 * abbe_five_eval_f32_rotary adds the rotary axes' part of m5 at p and udeg
 * (at and at + 3), or for m5 NULL (a 3-axis model) leaves the position
 * error, orientation 0. */
#define ABBE_FIVE_AT (ABBE_AXES + ABBE_ROTARY_AXES)
abbe_status_t abbe_five_eval_f32_linear(const abbe_model_t *m, const float pos_mm[3], const float angle_deg[2],
                                        const float dir_state[3], const float temp_c[3], abbe_five_error_f32_t *out,
                                        int32_t at[ABBE_FIVE_AT]);
void abbe_five_eval_f32_rotary(const abbe_five_model_t *m5, const int32_t p[3], const int32_t udeg[2],
                               abbe_five_error_f32_t *out);

/* The *out of a refused input (cold path). */
void abbe_f32_refuse(abbe_error_f32_t *out);

#endif /* ABBE_INTERNAL_H */
