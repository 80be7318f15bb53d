/* abbe: x86-64 (SSE2) kernels of the single-precision evaluation, inline for
 * eval_f32_sse2.c and terms_f32.c. SSE2 is part of every x86-64, so these
 * need no run-time dispatch. Same arithmetic as the plain C kernels, four
 * lanes at a time:
 *
 *   - sin/cos of four phases at once (the same polynomials and quarter-turn
 *     reduction as sincos_f32.h, the quarter applied with masks);
 *   - the dot products two rows (12 coefficients, three unaligned 16-byte
 *     loads) per step, times the lanes of p = [b0, b1, b0, b1], b0 the basis
 *     value of the first row, b1 of the second: lanes of a = columns 0-3 of
 *     first rows, of b = columns 4, 5 of first rows and 0, 1 of second rows,
 *     of c = columns 2-5 of second rows. A Fourier harmonic is such a pair
 *     (sin, cos), and rotating [s, c, s, c] to the next harmonic is a shuffle,
 *     two multiplies and an add.
 */
#ifndef ABBE_KERNEL_F32_SSE2_H
#define ABBE_KERNEL_F32_SSE2_H

#include "internal.h"

#if defined(ABBE_F32_SSE2)
#if defined(__AVX2__)
#include <immintrin.h> /* the x86-64-v3 build (eval_f32_avx2.c) */
#else
#include <emmintrin.h>
#endif

/* Unaligned loads and stores through memcpy: one movups/movq each, and no
 * pointer cast that would claim an alignment the blob does not promise. */
static ABBE_ALWAYS_INLINE __m128 abbe_ld4(const void *p)
{
    __m128 v;
    memcpy(&v, p, sizeof v);
    return v;
}

static ABBE_ALWAYS_INLINE __m128 abbe_ld2(const void *p) /* two floats, upper lanes 0 */
{
    /* one movq (a memcpy into a zeroed vector went through the stack); the
     * intrinsic reads through an unaligned may-alias type (void * converts to it) */
    return _mm_castsi128_ps(_mm_loadl_epi64(p));
}

static ABBE_ALWAYS_INLINE __m128i abbe_ld4i(const void *p)
{
    __m128i v;
    memcpy(&v, p, sizeof v);
    return v;
}

#if defined(__AVX2__)
static ABBE_ALWAYS_INLINE __m256i abbe_ld8i(const void *p)
{
    __m256i v;
    memcpy(&v, p, sizeof v);
    return v;
}
#endif

static ABBE_ALWAYS_INLINE void abbe_st2(void *p, __m128 v) /* the two low lanes */
{
    memcpy(p, &v, 8);
}

/* A broadcast or permutation of the lanes of v (pshufd: one instruction
 * that, unlike shufps, keeps its source). */
#define ABBE_PERMUTE(v, imm) _mm_castsi128_ps(_mm_shuffle_epi32(_mm_castps_si128(v), (imm)))

/* The vector constants, in one read-only block read through a pointer the
 * compiler cannot see through: each then stays a memory operand, where GCC
 * would rebuild a literal vector in registers (up to three instructions). */
typedef union {
    float f[4];
    int32_t i[4];
    __m128 v; /* 16-byte alignment: SSE2 memory operands need it */
} abbe_k4_t;

typedef struct {
    abbe_k4_t abs_mask, mm_limit, finite_max, sign, nm_per_mm, round_magic, mega, round_magic_bits;
    abbe_k4_t half_quarter, u_scale, s3, s2, s1, s0, c4, c3, c2, c1, one_f, one_i;
    abbe_k4_t sign_odd; /* [0, -0, 0, -0] */
    abbe_k4_t sign_lane0, sign_lane1, sign_lane2, um_per_lever, um_per_lin_neg, um_per_lin;
    abbe_k4_t cheb_bias, cheb_scale, cheb_one_q30; /* AVX2 Chebyshev arguments */
    abbe_k4_t even_words[2]; /* AVX2: VPERMD indices 0, 2, 4, 6: the low words of four 64-bit lanes */
} abbe_x86_consts_t;

#define ABBE_K4F(x) {.f = {(x), (x), (x), (x)}}
#define ABBE_K4I(x) {.i = {(x), (x), (x), (x)}}
static const abbe_x86_consts_t abbe_x86_consts_data = {
    ABBE_K4I(0x7FFFFFFF), ABBE_K4I(0x45063000), ABBE_K4I(0x7F7FFFFF), ABBE_K4I(INT32_MIN),
    ABBE_K4F(1.0e6f), ABBE_K4F(12582912.0f), ABBE_K4I(1000000), ABBE_K4I(0x4B400000),
    ABBE_K4I(1 << 29), ABBE_K4F(1.86264514923095703125e-9f), /* 2^29, 2^-29 */
    ABBE_K4F(-3.588928186218254e-05f), ABBE_K4F(0.0024898941721767187f), ABBE_K4F(-0.08074537664651871f),
    ABBE_K4F(0.7853981256484985f), ABBE_K4F(3.5318628215463832e-06f), ABBE_K4F(-0.00032594305230304599f),
    ABBE_K4F(0.015854328870773315f), ABBE_K4F(-0.30842512845993042f), ABBE_K4F(1.0f), ABBE_K4I(1),
    {.i = {0, INT32_MIN, 0, INT32_MIN}},
    {.i = {INT32_MIN, 0, 0, 0}}, {.i = {0, INT32_MIN, 0, 0}}, {.i = {0, 0, INT32_MIN, 0}},
    ABBE_K4F(2.9103830456733704e-14f), ABBE_K4F(-3.90625e-6f), ABBE_K4F(3.90625e-6f),
    ABBE_K4I(INT32_MIN), ABBE_K4F(9.31322574615478515625e-10f), ABBE_K4I(1 << 30),
    {{.i = {0, 2, 4, 6}}, {.i = {0, 2, 4, 6}}},
};
#undef ABBE_K4F
#undef ABBE_K4I

static ABBE_ALWAYS_INLINE const abbe_x86_consts_t *abbe_x86_consts(void)
{
    const abbe_x86_consts_t *k = &abbe_x86_consts_data;
    __asm__("" : "+r"(k)); /* opaque: the loads stay loads */
    return k;
}

/* The same pointer, again opaque: for a second use of constants that GCC
 * would otherwise load into registers once, early, for both uses (and then
 * spill, in a function that needs every register in between). */
static ABBE_ALWAYS_INLINE const abbe_x86_consts_t *abbe_x86_consts_again(void)
{
    const abbe_x86_consts_t *k = &abbe_x86_consts_data;
    __asm__ volatile("" : "+r"(k));
    return k;
}

#define ABBE_KV(k, name) ((k)->name.v)
#define ABBE_KI(k, name) _mm_castps_si128((k)->name.v)

/* sin and cos of four phases (fractions of a turn, Q32). */
static ABBE_ALWAYS_INLINE void abbe_sincos4_sse2(const abbe_x86_consts_t *k, __m128i phase, __m128 *sin_out,
                                                 __m128 *cos_out)
{
    const __m128i quarter = _mm_srli_epi32(_mm_add_epi32(phase, ABBE_KI(k, half_quarter)), 30);
    const __m128i r = _mm_sub_epi32(phase, _mm_slli_epi32(quarter, 30)); /* [-2^29, 2^29) */
    const __m128 u = _mm_mul_ps(_mm_cvtepi32_ps(r), ABBE_KV(k, u_scale));
    const __m128 z = _mm_mul_ps(u, u);
    __m128 s = _mm_add_ps(_mm_mul_ps(ABBE_KV(k, s3), z), ABBE_KV(k, s2));
    s = _mm_add_ps(_mm_mul_ps(s, z), ABBE_KV(k, s1));
    s = _mm_mul_ps(_mm_add_ps(_mm_mul_ps(s, z), ABBE_KV(k, s0)), u);
    __m128 c = _mm_add_ps(_mm_mul_ps(ABBE_KV(k, c4), z), ABBE_KV(k, c3));
    c = _mm_add_ps(_mm_mul_ps(c, z), ABBE_KV(k, c2));
    c = _mm_add_ps(_mm_mul_ps(c, z), ABBE_KV(k, c1));
    c = _mm_add_ps(_mm_mul_ps(c, z), ABBE_KV(k, one_f));
    /* quarter 0: (s, c), 1: (c, -s), 2: (-s, -c), 3: (-c, s) */
    const __m128i one = ABBE_KI(k, one_i);
    const __m128 swap = _mm_castsi128_ps(_mm_cmpeq_epi32(_mm_and_si128(quarter, one), one));
    const __m128 x = _mm_and_ps(_mm_xor_ps(s, c), swap);
    const __m128 neg_s = _mm_castsi128_ps(_mm_slli_epi32(_mm_srli_epi32(quarter, 1), 31));
    const __m128 neg_c = _mm_castsi128_ps(_mm_slli_epi32(_mm_srli_epi32(_mm_add_epi32(quarter, one), 1), 31));
    *sin_out = _mm_xor_ps(_mm_xor_ps(s, x), neg_s);
    *cos_out = _mm_xor_ps(_mm_xor_ps(c, x), neg_c);
}

/* [s, c, s, c] and the rotation by the fundamental of a block. */
typedef struct {
    __m128 p;     /* [s, c, s, c] of harmonic 1 */
    __m128 rot_c; /* [c, c, c, c] */
    __m128 rot_s; /* [s, -s, s, -s] */
} abbe_harmonic1_sse2_t;

static ABBE_ALWAYS_INLINE abbe_harmonic1_sse2_t abbe_harmonic1_sse2(const abbe_x86_consts_t *k, __m128 p)
{
    abbe_harmonic1_sse2_t h;
    h.p = p;
    h.rot_c = ABBE_PERMUTE(p, 0x55);
    h.rot_s = _mm_xor_ps(ABBE_PERMUTE(p, 0x00), ABBE_KV(k, sign_odd));
    return h;
}

#define ABBE_PAIR6_SSE2(pv)                                                                \
    do {                                                                                   \
        const __m128 p_ = (pv);                                                            \
        a = _mm_add_ps(a, _mm_mul_ps(abbe_ld4(row), ABBE_PERMUTE(p_, 0x00))); \
        b = _mm_add_ps(b, _mm_mul_ps(abbe_ld4(row + 16), ABBE_PERMUTE(p_, 0x50))); \
        c = _mm_add_ps(c, _mm_mul_ps(abbe_ld4(row + 32), ABBE_PERMUTE(p_, 0x55))); \
        row += 48;                                                                         \
    } while (0)

/* next harmonic: [s c1 + c s1, c c1 - s s1, ...] */
#define ABBE_ROTATE_SSE2(p, h1)                                                            \
    p = _mm_add_ps(_mm_mul_ps(p, (h1).rot_c), _mm_mul_ps(ABBE_PERMUTE(p, 0xB1), (h1).rot_s))

/* The h harmonics of one block, unrolled (a jump into the sequence; the
 * format caps h at 8): h pairs and h - 1 rotations. The rotation vectors are
 * made only for a block in use. */
#define ABBE_HARMONICS_SSE2(h, pv)                                                         \
    do {                                                                                   \
        const unsigned hn_ = (h);                                                          \
        if (hn_ == 0u) {                                                                   \
            break;                                                                         \
        }                                                                                  \
        const abbe_harmonic1_sse2_t h1 = abbe_harmonic1_sse2(k, pv);                          \
        __m128 q_ = h1.p;                                                                  \
        switch ((hn_ - 1u) & 7u) { /* h = 1..8 as 0..7: every value a case, no range check */ \
        case 7: ABBE_PAIR6_SSE2(q_); ABBE_ROTATE_SSE2(q_, h1); /* fallthrough */           \
        case 6: ABBE_PAIR6_SSE2(q_); ABBE_ROTATE_SSE2(q_, h1); /* fallthrough */           \
        case 5: ABBE_PAIR6_SSE2(q_); ABBE_ROTATE_SSE2(q_, h1); /* fallthrough */           \
        case 4: ABBE_PAIR6_SSE2(q_); ABBE_ROTATE_SSE2(q_, h1); /* fallthrough */           \
        case 3: ABBE_PAIR6_SSE2(q_); ABBE_ROTATE_SSE2(q_, h1); /* fallthrough */           \
        case 2: ABBE_PAIR6_SSE2(q_); ABBE_ROTATE_SSE2(q_, h1); /* fallthrough */           \
        case 1: ABBE_PAIR6_SSE2(q_); ABBE_ROTATE_SSE2(q_, h1); /* fallthrough */           \
        default: ABBE_PAIR6_SSE2(q_); break; /* 0: the last (or only) harmonic */          \
        }                                                                                  \
    } while (0)

/* The six term values of a fitted axis (n_terms = 6), in the coefficients'
 * units: lo = [d_x, d_y, d_z, eps_x], hi = [eps_y, eps_z, -, -]. ub: the
 * Chebyshev argument in all lanes (ignored without a trend of degree >= 1);
 * p0, p1: the blocks' harmonic 1 as [s, c, s, c] (ignored for an unused block). */
static ABBE_ALWAYS_INLINE void abbe_axis6_sse2(const abbe_x86_consts_t *k, const abbe_axis_model_t *ax, __m128 ub,
                                               __m128 p0, __m128 p1, __m128 *lo, __m128 *hi)
{
    const uint8_t *row = ax->coef_f32;
    __m128 a = _mm_setzero_ps(), b = _mm_setzero_ps(), c = _mm_setzero_ps();
    const unsigned trend_rows = ax->trend_rows;
    if (trend_rows > 1u) {
        /* ub = [u, u, u, u], the Chebyshev argument (from the caller).
         * T_0 = 1, T_1 = u: the first pair, with its ones folded in */
        a = abbe_ld4(row);
        b = _mm_mul_ps(abbe_ld4(row + 16), _mm_movelh_ps(ABBE_KV(k, one_f), ub));
        c = _mm_mul_ps(abbe_ld4(row + 32), ub);
        row += 48;
        if (trend_rows > 2u) { /* degree 2 and up (a linear trend skips this with one test) */
            const float u = _mm_cvtss_f32(ub), two_u = u + u;
            float t0 = 1.0f, t1 = u; /* T_(k-2), T_(k-1) */
            unsigned row_k = 2;
            for (; row_k + 1u < trend_rows; row_k += 2u) {
                t0 = two_u * t1 - t0; /* T_k = 2u T_(k-1) - T_(k-2) */
                t1 = two_u * t0 - t1;
                ABBE_PAIR6_SSE2(_mm_setr_ps(t0, t1, t0, t1));
            }
            if (row_k < trend_rows) { /* a last trend row alone */
                const __m128 t_ = _mm_set1_ps(two_u * t1 - t0);
                a = _mm_add_ps(a, _mm_mul_ps(abbe_ld4(row), t_));
                b = _mm_add_ps(b, _mm_mul_ps(abbe_ld2(row + 16), t_));
                row += 24;
            }
        }
    } else if (trend_rows == 1u) { /* T_0 = 1 alone: columns 0-3 to a, 4, 5 to b's low lanes */
        a = abbe_ld4(row);
        b = abbe_ld2(row + 16);
        row += 24;
    }
    ABBE_HARMONICS_SSE2(ax->harmonics[0], p0);
    ABBE_HARMONICS_SSE2(ax->harmonics[1], p1);
    *lo = _mm_add_ps(a, _mm_shuffle_ps(b, c, 0x4E)); /* a + [b2, b3, c0, c1] */
    *hi = _mm_add_ps(b, _mm_movehl_ps(c, c));        /* b + [c2, c3, ..] */
}

#endif /* ABBE_F32_SSE2 */
#endif /* ABBE_KERNEL_F32_SSE2_H */
