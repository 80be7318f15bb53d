/* abbe: the five-axis evaluation's single-precision kernels (five_eval_f32.c):
 * an axis' share of Eq. 3 together with its angles (one pass of the basis for
 * both), and a rotary axis' six error motions by the Fourier blocks' loop.
 * Their own translation unit: the 3-axis kernels (terms_f32.c) are compiled
 * exactly as without them. */
#include "kernel_f32.h"

#if !ABBE_WITH_F32
#error "this is the _f32 variant: compile it with ABBE_WITH_F32=1 (or leave it undefined), or leave the file out"
#endif

#if !defined(ABBE_F32_SSE2)

/* The five-axis evaluation's kernels (abbe_axis_fold_rot_f32): also the angles.
 * e and w in memory (the caller's output), not returned: GCC 12 keeps 32 unused
 * bytes of stack in every function returning the three floats (bench/results.md,
 * section 11), and e then need not stay in registers across the basis loop. */
ABBE_NOINLINE static void fold6_rot_f32(const abbe_axis_model_t *ax, uint32_t d, float e[3], float w[3], float wsign,
                                        float rx, float ry, float rz, float lin)
{
    const abbe_vec3f_t f = fold6_body(ax, d, e[0], e[1], e[2], rx, ry, rz, lin, w, wsign);
    e[0] = f.x;
    e[1] = f.y;
    e[2] = f.z;
}

#endif /* !ABBE_F32_SSE2 */

/* An axis whose six values come as an array (a sparse axis; every axis on
 * x86-64, whose kernels return values), folded as by the kernel above. Out
 * of line: the values' array is not on the stack of the six-term path. */
ABBE_NOINLINE static void fold_values_rot_f32(const abbe_axis_model_t *ax, uint32_t d, float e[3], float w[3],
                                              float wsign, float rx, float ry, float rz, float lin)
{
    float v[ABBE_TERMS];
#if defined(ABBE_F32_SSE2)
    abbe_axis_terms_f32(ax, d, v);
#else
    abbe_axis_terms_sparse_f32(ax, d, v);
#endif
    abbe_vec3f_t f = {e[0], e[1], e[2]};
    const abbe_vec3f_t r = {rx, ry, rz};
    ABBE_FOLD6(f, r, lin, v[0], v[1], v[2], v[3], v[4], v[5]);
    w[0] += wsign * v[3];
    w[1] += wsign * v[4];
    w[2] += wsign * v[5];
    e[0] = f.x;
    e[1] = f.y;
    e[2] = f.z;
}

void abbe_axis_fold_rot_f32(const abbe_axis_model_t *ax, uint32_t d, float e[3], float w[3], float wsign, float rx,
                            float ry, float rz, float lin)
{
#if !defined(ABBE_F32_SSE2)
    if (ax->n_terms == ABBE_TERMS) {
        fold6_rot_f32(ax, d, e, w, wsign, rx, ry, rz, lin);
        return;
    }
#endif
    fold_values_rot_f32(ax, d, e, w, wsign, rx, ry, rz, lin);
}

/* A rotary axis' six error motions (format 1.2, five_eval_f32.c): the sums
 * over k = 1..h of the rows sin(k t), cos(k t), by the loop of a Fourier
 * block above, the first three times lin, the others times ang; h >= 1,
 * (s1, c1) = (sin t, cos t). */
void abbe_rotary_motions6_f32(const uint8_t *row, unsigned h, float s1, float c1, float lin, float ang, float m[6])
{
    ACC6_DECL();
    ZERO6();
    HARM6(s1, c1, h);
    m[0] = a0 * lin;
    m[1] = a1 * lin;
    m[2] = a2 * lin;
    m[3] = a3 * ang;
    m[4] = a4 * ang;
    m[5] = a5 * ang;
}
