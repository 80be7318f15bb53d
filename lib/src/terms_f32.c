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
#include "kernel_f32.h"

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

/* The 3-axis evaluation's kernel (abbe_axis_fold_f32). */
ABBE_NOINLINE static abbe_vec3f_t fold6_f32(const abbe_axis_model_t *ax, uint32_t d, float ex, float ey,
                                            float ez, float rx, float ry, float rz, float lin)
{
    return fold6_body(ax, d, ex, ey, ez, rx, ry, rz, lin, NULL, 0.0f);
}

#endif /* ABBE_F32_SSE2 */

/* A sparse axis (n_terms < 6 packed columns): rare, so built for a small
 * stack and little code rather than for speed: one column at a time, each
 * with its own pass of the basis and a single accumulator. */
ABBE_NOINLINE void abbe_axis_terms_sparse_f32(const abbe_axis_model_t *ax, uint32_t d, float value[ABBE_TERMS])
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
#define ZERO1() do { acc = 0.0f; } while (0)
#define FIRST1() do { acc = LD(0); row += stride; } while (0)
#define ROW1(b) do { acc += LD(0) * (b); row += stride; } while (0)
#define HARM1(s1v, c1v, hv) ABBE_HARMONICS_C(ROW1, s1v, c1v, hv)
        ABBE_BASIS_F32(ax, d, ZERO1, FIRST1, ROW1, HARM1);
#undef HARM1
#undef ZERO1
#undef FIRST1
#undef ROW1
        value[t] = acc;
    }
}

#if !defined(ABBE_F32_SSE2)
abbe_vec3f_t abbe_axis_fold_f32(const abbe_axis_model_t *ax, uint32_t d, float ex, float ey, float ez, float rx,
                                float ry, float rz, float lin)
{
    if (ax->n_terms == ABBE_TERMS) {
        return fold6_f32(ax, d, ex, ey, ez, rx, ry, rz, lin);
    }
    abbe_vec3f_t e = {ex, ey, ez};
    const abbe_vec3f_t r = {rx, ry, rz};
    float v[ABBE_TERMS];
    abbe_axis_terms_sparse_f32(ax, d, v);
    ABBE_FOLD6(e, r, lin, v[0], v[1], v[2], v[3], v[4], v[5]);
    return e;
}
#endif

#undef HARM6
#undef ROW6_ASM
#undef ZERO6
#undef FIRST6
#undef ROW6
#undef ACC6_DECL
#undef LD

void abbe_axis_terms_f32(const abbe_axis_model_t *ax, uint32_t d, float value[ABBE_TERMS])
{
    if (ax->n_terms != ABBE_TERMS) {
        abbe_axis_terms_sparse_f32(ax, d, value);
        return;
    }
#if defined(ABBE_F32_SSE2)
    terms6_f32(ax, d, value);
#else
    /* The six values from the folding kernel, with unit weights (exact: every
     * product is by 0 or 1, every sum adds zeros): lin = 1, r = 0 gives
     * (d_x, d_y, d_z); r = (1, 0, 0) gives (0, eps_z, -eps_y); r = (0, 1, 0)
     * gives (-eps_z, 0, eps_x). Not on the hot path (abbe_term_eval_f32). */
    const abbe_vec3f_t lin = fold6_f32(ax, d, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 1.0f);
    const abbe_vec3f_t rx = fold6_f32(ax, d, 0.0f, 0.0f, 0.0f, 1.0f, 0.0f, 0.0f, 0.0f);
    const abbe_vec3f_t ry = fold6_f32(ax, d, 0.0f, 0.0f, 0.0f, 0.0f, 1.0f, 0.0f, 0.0f);
    value[0] = lin.x;
    value[1] = lin.y;
    value[2] = lin.z;
    value[3] = ry.z;
    value[4] = -rx.z;
    value[5] = rx.y;
#endif
}

abbe_status_t abbe_mm_to_nm_f32(float mm, int32_t *nm, uint32_t *flags)
{
    return abbe_mm_to_nm_inline(mm, nm, flags) ? ABBE_E_INPUT : ABBE_OK;
}
