/* abbe: five-axis tool tip error, single precision (abbe/five_axis.h).
 *
 * The first-order model of abbe.model.five_axis.tool_error_linear
 * (docs/concepts.md, "Five-axis machines"):
 *
 *   E = e_lin - R_t d_C - d_t,   W = w_lin - R_t w_C - w_t
 *
 * with each rotary axis' twist at its angle t and a lever L from its pivot:
 *   w = (I - R) phi + E0 k + m_rot(t),   d = (I - R) delta + w x L + m_trans(t)
 * (the C axis' lever is R_t^T (q - P_t) + offset, the tilt's q - P_t). The
 * linear axes' part is the 3-axis evaluation (eval_f32.c) plus the five-axis
 * squareness; their orientation error is eps_Z - eps_X - eps_Y.
 *
 * Angles become integer micro-degrees (abbe_mm_to_nm_inline's exact
 * conversion: the same 10^6 scale) and a phase in Q32 turns, reduced modulo
 * one turn in integers first, so a full turn is an exact period.
 */
#include "internal.h"

#if !ABBE_WITH_F32
#error "this is the _f32 variant: compile it with ABBE_WITH_F32=1 (or leave it undefined), or leave the file out"
#endif

#define UM_PER_Q8 3.90625e-6f                 /* 2^-8 nm in um */
#define URAD_PER_Q36 1.4551915228366852e-5f   /* 2^-36 rad in urad */
#define MM_PER_HALF_NM 2.0e-6f

/* v -> R v (inverse: R^T v) for a rotation by (c, s) about machine axis k. */
static void rotate_f32(unsigned k, float c, float s, int inverse, float v[3])
{
    const unsigned j = (k + 1u) % 3u, l = (k + 2u) % 3u;
    const float sn = inverse ? -s : s;
    const float vj = v[j], vl = v[l];
    v[j] = c * vj - sn * vl;
    v[l] = sn * vj + c * vl;
}

/* The error motions m (X, Y, Z um; A, B, C urad) of an axis at its angle
 * (c, s): sin k t and cos k t by rotation, k = 1 .. H. An axis with all six
 * components (the fitted case) keeps its accumulators in registers. */
ABBE_NOINLINE static void motions_f32(const abbe_rotary_model_t *ax, float c, float s, float m[ABBE_MOTIONS])
{
    const unsigned n = ax->n_comp;
    const uint8_t *row = ax->coef_f32;
    float sk = s, ck = c;
    if (n == ABBE_MOTIONS) {
        float a0 = 0.0f, a1 = 0.0f, a2 = 0.0f, a3 = 0.0f, a4 = 0.0f, a5 = 0.0f;
        for (unsigned k = 0; k < ax->harmonics; k++, row += 48u) {
#define MAC6(acc, i) acc += abbe_ld_f32_aligned(row + 4u * (i)) * sk + abbe_ld_f32_aligned(row + 24u + 4u * (i)) * ck
            MAC6(a0, 0u); MAC6(a1, 1u); MAC6(a2, 2u); MAC6(a3, 3u); MAC6(a4, 4u); MAC6(a5, 5u);
#undef MAC6
            const float sn = sk * c + ck * s;
            ck = ck * c - sk * s;
            sk = sn;
        }
        m[0] = a0 * UM_PER_Q8; m[1] = a1 * UM_PER_Q8; m[2] = a2 * UM_PER_Q8;
        m[3] = a3 * URAD_PER_Q36; m[4] = a4 * URAD_PER_Q36; m[5] = a5 * URAD_PER_Q36;
        return;
    }
    float acc[ABBE_MOTIONS];
    for (unsigned i = 0; i < ABBE_MOTIONS; i++) {
        acc[i] = 0.0f;
    }
    for (unsigned k = 0; k < ax->harmonics; k++) {
        for (unsigned col = 0; col < n; col++) {
            acc[col] += abbe_ld_f32_aligned(row + 4u * col) * sk + abbe_ld_f32_aligned(row + 4u * (n + col)) * ck;
        }
        row += 8u * n;
        const float sn = sk * c + ck * s;
        ck = ck * c - sk * s;
        sk = sn;
    }
    for (unsigned i = 0; i < ABBE_MOTIONS; i++) {
        m[i] = ax->column[i] == 0xFFu ? 0.0f : acc[ax->column[i]] * (i < 3u ? UM_PER_Q8 : URAD_PER_Q36);
    }
}

/* An axis' twist at its angle (c, s) for a point at lever L (mm): d (um),
 * w (urad). */
ABBE_NOINLINE static void twist_f32(const abbe_rotary_model_t *ax, float c, float s, const float L_mm[3], float d_um[3],
                                    float w_urad[3])
{
    float m[ABBE_MOTIONS];
    motions_f32(ax, c, s, m);
    /* w = (I - R) phi + E0 k + m_rot, d = (I - R) delta + m_trans, componentwise
     * (no component along the axis k) */
    const unsigned k = ax->dir, j = (k + 1u) % 3u, l = (k + 2u) % 3u;
    const float pj = (float)ax->phi_q36[j] * URAD_PER_Q36, pl = (float)ax->phi_q36[l] * URAD_PER_Q36;
    const float dj = (float)ax->delta_q8[j] * UM_PER_Q8, dl = (float)ax->delta_q8[l] * UM_PER_Q8;
    float w[3], d[3];
    w[k] = (float)ax->zero_q36 * URAD_PER_Q36;
    w[j] = pj - (c * pj - s * pl);
    w[l] = pl - (s * pj + c * pl);
    d[k] = 0.0f;
    d[j] = dj - (c * dj - s * dl);
    d[l] = dl - (s * dj + c * dl);
    for (unsigned i = 0; i < 3u; i++) {
        w_urad[i] = w[i] + m[3u + i];
    }
    /* w x L: urad x mm = nm */
    d_um[0] = d[0] + (w_urad[1] * L_mm[2] - w_urad[2] * L_mm[1]) * 1.0e-3f + m[0];
    d_um[1] = d[1] + (w_urad[2] * L_mm[0] - w_urad[0] * L_mm[2]) * 1.0e-3f + m[1];
    d_um[2] = d[2] + (w_urad[0] * L_mm[1] - w_urad[1] * L_mm[0]) * 1.0e-3f + m[2];
}

/* out's position (um) and orientation (urad) minus the rotary axes' twists,
 * plus the five-axis squareness, at positions p (nm) and angles udeg. Out of
 * line: its frame and the linear evaluation's are never on the stack
 * together. */
ABBE_NOINLINE static void add_rotary_f32(const abbe_five_model_t *m5, const int32_t p[3], const int32_t udeg[2],
                                         abbe_five_error_f32_t *out)
{
    const abbe_rotary_model_t *tilt = &m5->rotary[0], *table = &m5->rotary[1];
    float st, ct, sc, cc;
    abbe_sincos_f32(abbe_udeg_phase_q32(udeg[0]), &st, &ct);
    abbe_sincos_f32(abbe_udeg_phase_q32(udeg[1]), &sc, &cc);
    float L[3], d[3], w[3];
    /* the table axis C at the point before the tilt's rotation: lever R_t^T (q - P_t) + offset,
     * (p >> 1) - (P >> 1) an exact int32 difference of half positions */
    for (unsigned i = 0; i < 3u; i++) {
        L[i] = (float)((p[i] >> 1) - (m5->tilt_pivot_nm[i] >> 1)) * MM_PER_HALF_NM;
    }
    rotate_f32(tilt->dir, ct, st, 1, L);
    for (unsigned i = 0; i < 3u; i++) {
        L[i] += (float)m5->offset_nm[i] * 1.0e-6f;
    }
    twist_f32(table, cc, sc, L, d, w);
    rotate_f32(tilt->dir, ct, st, 0, d);
    rotate_f32(tilt->dir, ct, st, 0, w);
    for (unsigned i = 0; i < 3u; i++) {
        out->error_um[i] -= d[i];
        out->orient_urad[i] -= w[i];
        L[i] = (float)((p[i] >> 1) - (m5->tilt_pivot_nm[i] >> 1)) * MM_PER_HALF_NM; /* the tilt: q - P_t */
    }
    twist_f32(tilt, ct, st, L, d, w);
    for (unsigned i = 0; i < 3u; i++) {
        out->error_um[i] -= d[i];
        out->orient_urad[i] -= w[i];
    }
    /* five-axis squareness, lever y, z from the C centre: mm x urad = nm */
    const float y = (float)((p[1] >> 1) - (m5->rot_point_nm[1] >> 1)) * MM_PER_HALF_NM;
    const float z = (float)((p[2] >> 1) - (m5->rot_point_nm[2] >> 1)) * MM_PER_HALF_NM;
    out->error_um[0] += (y * (float)m5->squareness_q36[0] - z * (float)m5->squareness_q36[1]) * (URAD_PER_Q36 * 1.0e-3f);
    out->error_um[1] -= z * (float)m5->squareness_q36[2] * (URAD_PER_Q36 * 1.0e-3f);
}

static void refuse(abbe_five_error_f32_t *out)
{
    for (unsigned i = 0; i < 3u; i++) {
        out->error_um[i] = 0.0f;
        out->orient_urad[i] = 0.0f;
    }
    out->flags = 0;
}

abbe_status_t abbe_five_error_eval_f32(const abbe_five_model_t *m5, const abbe_five_input_f32_t *in,
                                       abbe_five_error_f32_t *out)
{
    if (m5 == NULL || in == NULL || out == NULL) {
        return ABBE_E_ARG;
    }
    const abbe_model_t *m = &m5->linear;
    abbe_input_f32_t lin_in;
    abbe_error_f32_t lin;
    memcpy(lin_in.pos_mm, in->pos_mm, sizeof lin_in.pos_mm);
    memcpy(lin_in.dir_state, in->dir_state, sizeof lin_in.dir_state);
    memcpy(lin_in.temp_c, in->temp_c, sizeof lin_in.temp_c);
    if (abbe_eval_f32_core(m, &lin_in, &lin) != ABBE_OK) {
        refuse(out);
        return ABBE_E_INPUT;
    }
    uint32_t flags = lin.flags, bad = 0;
    int32_t p[3], udeg[2];
    for (unsigned j = 0; j < 3u; j++) {
        uint32_t ignored = 0; /* the 3-axis evaluation flagged these already */
        (void)abbe_mm_to_nm_inline(in->pos_mm[j], &p[j], &ignored);
    }
    for (unsigned r = 0; r < ABBE_ROTARY_AXES; r++) {
        bad |= abbe_mm_to_nm_inline(in->angle_deg[r], &udeg[r], &flags); /* the same 10^6 scale */
    }
    if (bad) {
        refuse(out);
        return ABBE_E_INPUT;
    }
    /* the linear axes' orientation error eps_Z - eps_X - eps_Y (axes with angular terms only) */
    float rot[3] = {0.0f, 0.0f, 0.0f};
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        const abbe_axis_model_t *ax = &m->axis[j];
        if ((ax->term_mask & 0x38u) == 0u) {
            continue;
        }
        float v[ABBE_TERMS];
        uint32_t ignored = 0;
        abbe_axis_terms_f32(ax, abbe_arg_offset(ax, p[j], &ignored), v);
        const float sign = j == 2u ? URAD_PER_Q36 : -URAD_PER_Q36;
        for (unsigned c = 0; c < 3u; c++) {
            rot[c] += sign * v[3u + c];
        }
    }
    for (unsigned i = 0; i < 3u; i++) {
        out->error_um[i] = lin.error_um[i];
        out->orient_urad[i] = rot[i];
    }
    if (m5->kind != ABBE_KIN_NONE) {
        add_rotary_f32(m5, p, udeg, out);
    }
    out->flags = flags;
    return ABBE_OK;
}
