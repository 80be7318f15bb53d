/* abbe: five-axis tool tip error, single precision (abbe/five_axis.h).
 *
 * The first-order model of abbe.model.five_axis.tool_error_linear
 * (docs/concepts.md, "Five-axis machines"):
 *
 *   E = e_lin - R_t d_C - d_t,   W = w_lin - R_t w_C - w_t
 *
 * with each rotary axis' twist at its angle t and a lever L from its pivot:
 *   w = (I - R) phi + E0 k + m_rot(t),   d = (I - R) delta + w x L + m_trans(t)
 * (the C axis' lever is R_t^T (q - P_t) + offset, the tilt's q - P_t;
 * add_rotary_f32 rearranges it so that this lever is never formed). The
 * linear axes' part is the 3-axis evaluation's source (eval_f32_linear.h),
 * whose folds also sum their orientation error eps_Z - eps_X - eps_Y, plus
 * the five-axis squareness.
 *
 * Angles become integer micro-degrees (abbe_mm_to_nm_inline's exact
 * conversion: the same 10^6 scale) and a phase in Q32 turns, reduced modulo
 * one turn in integers first, so a full turn is an exact period.
 */
#define ABBE_EVAL_F32_ROT 1 /* the folds also sum the linear axes' angles */
#include "eval_f32_linear.h"

#if !ABBE_WITH_F32
#error "this is the _f32 variant: compile it with ABBE_WITH_F32=1 (or leave it undefined), or leave the file out"
#endif

#define UM_PER_Q8 3.90625e-6f                 /* 2^-8 nm in um */
#define URAD_PER_Q36 1.4551915228366852e-5f   /* 2^-36 rad in urad */
#define MM_PER_HALF_NM 2.0e-6f

/* The error motions m (X, Y, Z um; A, B, C urad) of an axis with fewer than
 * six components (or none) at its angle (c, s): one column at a time, sin k t
 * and cos k t by rotation, k = 1 .. H. */
ABBE_NOINLINE static void motions_sparse_f32(const abbe_rotary_model_t *ax, float c, float s, float m[ABBE_MOTIONS])
{
    const unsigned n = ax->n_comp, h = ax->harmonics; /* h = 0 without components (the loader) */
    if (h == 0u) { /* no error motions (location errors only) */
        m[0] = m[1] = m[2] = m[3] = m[4] = m[5] = 0.0f;
        return;
    }
    for (unsigned i = 0; i < ABBE_MOTIONS; i++) {
        float acc = 0.0f, sk = s, ck = c;
        const uint8_t *row = ax->coef_f32 + 4u * ax->column[i];
        for (unsigned k = 0; ax->column[i] != 0xFFu && k < h; k++, row += 8u * n) {
            acc += abbe_ld_f32_aligned(row) * sk;
            acc += abbe_ld_f32_aligned(row + 4u * n) * ck;
            const float sn = sk * c + ck * s;
            ck = ck * c - sk * s;
            sk = sn;
        }
        m[i] = acc * (i < 3u ? UM_PER_Q8 : URAD_PER_Q36);
    }
}

/* An axis' twist at its angle (c, s) without the lever, vw = (v, w):
 * v = (I - R) delta + m_trans (um), w = (I - R) phi + E0 k + m_rot (urad);
 * k the axis it turns about, (j, l) the other two in cyclic order (phi and
 * delta have no component along k). The motions are written straight into vw. */
static ABBE_ALWAYS_INLINE void twist_f32(const abbe_rotary_model_t *ax, unsigned k, unsigned j, unsigned l, float c,
                                         float s, float vw[2u * 3u])
{
    if (ax->n_comp == ABBE_MOTIONS && ax->harmonics != 0u) { /* the fitted case: the Fourier blocks' kernel */
        abbe_rotary_motions6_f32(ax->coef_f32, ax->harmonics, s, c, UM_PER_Q8, URAD_PER_Q36, vw);
    } else {
        motions_sparse_f32(ax, c, s, vw);
    }
    float *v = vw, *w = vw + 3;
    const float pj = (float)ax->phi_q36[j] * URAD_PER_Q36, pl = (float)ax->phi_q36[l] * URAD_PER_Q36;
    const float dj = (float)ax->delta_q8[j] * UM_PER_Q8, dl = (float)ax->delta_q8[l] * UM_PER_Q8;
    const float omc = 1.0f - c;
    w[k] += (float)ax->zero_q36 * URAD_PER_Q36;
    w[j] += omc * pj + s * pl;
    w[l] += omc * pl - s * pj;
    v[j] += omc * dj + s * dl;
    v[l] += omc * dl - s * dj;
}

/* out's position (um) and orientation (urad) minus the rotary axes' twists,
 * plus the five-axis squareness, at positions p (nm) and angles udeg. With
 * R_t the tilt's rotation (about its axis k, X or Y; (j, l) = (k+1, k+2) mod
 * 3), Lt = q - P_t the tilt's lever and the C axis' Lc = R_t^T Lt + offset,
 * R_t (w_C x Lc) = W_C x (Lt + R_t offset) with W_C = R_t w_C, so
 *   E -= R_t v_C + v_t + (W_C + w_t) x Lt + W_C x R_t offset,
 *   W -= W_C + w_t.
 * Out of line: its frame and the linear evaluation's are never on the stack
 * together. */
ABBE_NOINLINE static void add_rotary_f32(const abbe_five_model_t *m5, const int32_t p[3], const int32_t udeg[2],
                                         abbe_five_error_f32_t *out)
{
    const abbe_rotary_model_t *tilt = &m5->rotary[0], *table = &m5->rotary[1];
    const unsigned k = tilt->dir, j = k + 1u, l = k == 0u ? 2u : 0u; /* the tilt turns about X or Y */
    float st, ct, sc, cc;
    abbe_sincos_f32(abbe_udeg_phase_q32(udeg[0]), &st, &ct);
    abbe_sincos_f32(abbe_udeg_phase_q32(udeg[1]), &sc, &cc);
    float vw[6], vwt[6], Ro[3];
    twist_f32(table, 2u, 0u, 1u, cc, sc, vw);
    twist_f32(tilt, k, j, l, ct, st, vwt);
    float *v = vw, *w = vw + 3;
    const float *vt = vwt, *wt = vwt + 3;
    /* R_t of the table's v and w, and of the offset (no component along k: the loader), mm */
    const float vj = v[j], wj = w[j];
    v[j] = ct * vj - st * v[l];
    v[l] = st * vj + ct * v[l];
    w[j] = ct * wj - st * w[l];
    w[l] = st * wj + ct * w[l];
    const float oj = (float)m5->offset_nm[j] * 1.0e-6f, ol = (float)m5->offset_nm[l] * 1.0e-6f;
    Ro[k] = 0.0f;
    Ro[j] = ct * oj - st * ol;
    Ro[l] = st * oj + ct * ol;
    /* the tilt's lever q - P_t, mm: (p >> 1) - (P >> 1) an exact int32 difference of half positions */
    const float x = (float)((p[0] >> 1) - (m5->tilt_pivot_nm[0] >> 1)) * MM_PER_HALF_NM;
    const float y = (float)((p[1] >> 1) - (m5->tilt_pivot_nm[1] >> 1)) * MM_PER_HALF_NM;
    const float z = (float)((p[2] >> 1) - (m5->tilt_pivot_nm[2] >> 1)) * MM_PER_HALF_NM;
    const float W0 = w[0] + wt[0], W1 = w[1] + wt[1], W2 = w[2] + wt[2];
    /* urad x mm = nm */
    const float c0 = (W1 * z - W2 * y + w[1] * Ro[2] - w[2] * Ro[1]) * 1.0e-3f;
    const float c1 = (W2 * x - W0 * z + w[2] * Ro[0] - w[0] * Ro[2]) * 1.0e-3f;
    const float c2 = (W0 * y - W1 * x + w[0] * Ro[1] - w[1] * Ro[0]) * 1.0e-3f;
    /* five-axis squareness, lever y, z from the C centre: mm x urad = nm */
    const float sy = (float)((p[1] >> 1) - (m5->rot_point_nm[1] >> 1)) * MM_PER_HALF_NM;
    const float sz = (float)((p[2] >> 1) - (m5->rot_point_nm[2] >> 1)) * MM_PER_HALF_NM;
    const float q = URAD_PER_Q36 * 1.0e-3f;
    out->error_um[0] += (sy * (float)m5->squareness_q36[0] - sz * (float)m5->squareness_q36[1]) * q -
                        (v[0] + vt[0] + c0);
    out->error_um[1] -= sz * (float)m5->squareness_q36[2] * q + (v[1] + vt[1] + c1);
    out->error_um[2] -= v[2] + vt[2] + c2;
    out->orient_urad[0] -= W0;
    out->orient_urad[1] -= W1;
    out->orient_urad[2] -= W2;
}

static void refuse(abbe_five_error_f32_t *out)
{
    for (unsigned i = 0; i < 3u; i++) {
        out->error_um[i] = 0.0f;
        out->orient_urad[i] = 0.0f;
    }
    out->flags = 0;
}

abbe_status_t abbe_five_eval_f32_core(const abbe_model_t *m, const abbe_five_model_t *m5, const float pos_mm[3],
                                     const float angle_deg[2], const float dir_state[3], const float temp_c[3],
                                     abbe_five_error_f32_t *out)
{
    int32_t p[3], udeg[2];
    uint32_t flags = 0, bad = 0;
    float *w = out->orient_urad; /* the linear axes' eps_Z - eps_X - eps_Y, summed by their folds */
    w[0] = w[1] = w[2] = 0.0f;
    flags = eval_f32_linear(m, pos_mm, dir_state, temp_c, out->error_um, p, w);
    if (flags == ABBE_FLAG_INPUT_INVALID) { /* never set by the evaluation itself */
        refuse(out);
        return ABBE_E_INPUT;
    }
    for (unsigned r = 0; r < ABBE_ROTARY_AXES; r++) {
        bad |= abbe_mm_to_nm_inline(angle_deg[r], &udeg[r], &flags); /* the same 10^6 scale */
    }
    if (bad) {
        refuse(out);
        return ABBE_E_INPUT;
    }
    if (m5 == NULL) {
        w[0] = w[1] = w[2] = 0.0f; /* a 3-axis model under the compensator: its position error only */
    } else if (m5->kind != ABBE_KIN_NONE) {
        add_rotary_f32(m5, p, udeg, out);
    }
    out->flags = flags;
    return ABBE_OK;
}

abbe_status_t abbe_five_error_eval_f32(const abbe_five_model_t *m5, const abbe_five_input_f32_t *in,
                                       abbe_five_error_f32_t *out)
{
    if (m5 == NULL || in == NULL || out == NULL) {
        return ABBE_E_ARG;
    }
    return abbe_five_eval_f32_core(&m5->linear, m5, in->pos_mm, in->angle_deg, in->dir_state, in->temp_c, out);
}
