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
                                         float s, float sr, float vw[2u * 3u])
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
    /* sr: the rotation's sine (s, or -s for an axis turning about minus its machine axis);
     * the error motions are functions of the joint angle, s */
    w[j] += omc * pj + sr * pl;
    w[l] += omc * pl - sr * pj;
    v[j] += omc * dj + sr * dl;
    v[l] += omc * dl - sr * dj;
}

#if !defined(ABBE_NO_FIVE_KINDS)
/* kinds 3-5's out-of-line twist (below), also the trunnions' tilt's */
ABBE_NOINLINE static void twist_chain_f32(const abbe_rotary_model_t *ax, float c, float s, float sr, float vw[6]);
#endif

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
    twist_f32(table, 2u, 0u, 1u, cc, sc, sc, vw);
#if defined(ABBE_NO_FIVE_KINDS)
    twist_f32(tilt, k, j, l, ct, st, st, vwt);
#else
    /* the kinds' out-of-line twist (the same code, j and l from tilt->dir as above): one
     * copy less, -220 B of flash for +23 instructions (bench/results.md, section 11) */
    twist_chain_f32(tilt, ct, st, st, vwt);
#endif
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

#if !defined(ABBE_NO_FIVE_KINDS)
/* out = Rot_k(t) in, (c, s) = (cos t, sin t). Out of line, as the helpers below: the
 * other kinds' code is called rarely enough per image that flash wins (bench/results.md). */
ABBE_NOINLINE static void rotate_f32(unsigned k, float c, float s, const float in[3], float out[3])
{
    const unsigned j = k == 2u ? 0u : k + 1u, l = k == 0u ? 2u : k - 1u;
    const float a = in[j], b = in[l];
    out[k] = in[k];
    out[j] = c * a - s * b;
    out[l] = s * a + c * b;
}

/* a x b added to acc times f */
ABBE_NOINLINE static void cross_add_f32(const float a[3], const float b[3], float f, float acc[3])
{
    acc[0] += (a[1] * b[2] - a[2] * b[1]) * f;
    acc[1] += (a[2] * b[0] - a[0] * b[2]) * f;
    acc[2] += (a[0] * b[1] - a[1] * b[0]) * f;
}

/* Kinds 3-5 (format 1.4, docs/table-format.md "Other kinematic kinds"): the
 * linearised chain model of abbe.model.chain.tool_error_linear with the tool
 * tip at the controlled point. Record 0 is the outer axis (next to the linear
 * axes), record 1 the inner; each axis' twist (v, w) at its lever L from its
 * pivot is d = v + w x L. Nested pairs (kind 3 in the head, kind 5 under the
 * workpiece), with R0 record 0's rotation, L the outer axis' lever and
 * g = P0 - P1:
 *   d = v0 + R0 v1 + (w0 + R0 w1) x L + R0 w1 x R0 g,   w = w0 + R0 w1,
 * L = q - P0 under the workpiece (the tool error gets -d, -w), and
 * L = R0 (P1 - R1 P1 - P0) in the head (pivots relative to the controlled
 * point; the tool error gets +d, +w). Kind 4: the head's B alone (lever
 * -R_B P_B, +) and the table's C alone (lever q - P_C, -). */
/* A record's twist (twist_f32) about its own machine axis: one copy for both records
 * (and the trunnions' tilt, add_rotary_f32). */
ABBE_NOINLINE static void twist_chain_f32(const abbe_rotary_model_t *ax, float c, float s, float sr, float vw[6])
{
    const unsigned k = ax->dir;
    twist_f32(ax, k, k == 2u ? 0u : k + 1u, k == 0u ? 2u : k - 1u, c, s, sr, vw);
}

ABBE_NOINLINE static void add_chain_f32(const abbe_five_model_t *m5, const int32_t p[3], const int32_t udeg[2],
                                        abbe_five_error_f32_t *out)
{
    const abbe_rotary_model_t *r0 = &m5->rotary[0], *r1 = &m5->rotary[1];
    const unsigned k0 = r0->dir, k1 = r1->dir, kind = m5->kind;
    float s0, c0, s1, c1;
    abbe_sincos_f32(abbe_udeg_phase_q32(udeg[m5->slot[0]]), &s0, &c0);
    abbe_sincos_f32(abbe_udeg_phase_q32(udeg[m5->slot[1]]), &s1, &c1);
    const float s0r = (float)m5->sign[0] * s0, s1r = (float)m5->sign[1] * s1;
    /* v0 becomes the position part d, L0 starts as q - P0: fewer arrays, less stack */
    float vw0[6], vw1[6], P0[3], L0[3], L1[3], t[3];
    twist_chain_f32(r0, c0, s0, s0r, vw0);
    twist_chain_f32(r1, c1, s1, s1r, vw1);
    const int32_t *pv0 = kind == ABBE_KIN_XYZBC_HT ? m5->offset_nm : m5->rot_point_nm;
    const int32_t *pv1 = kind == ABBE_KIN_XYZBC_HT ? m5->rot_point_nm : m5->tilt_pivot_nm;
    for (unsigned i = 0; i < 3u; i++) {
        P0[i] = (float)pv0[i] * 1.0e-6f;
        L0[i] = (float)((p[i] >> 1) - (pv0[i] >> 1)) * MM_PER_HALF_NM; /* q - P0, exact halves */
    }
    float *v0 = vw0, *w0 = vw0 + 3, *v1 = vw1, *w1 = vw1 + 3;
    float sign = -1.0f; /* under the workpiece */
    if (kind == ABBE_KIN_XYZBC_HT) {
        /* head B: lever -R_B P_B; table C: lever q - P_C */
        rotate_f32(k0, c0, s0r, P0, L0);
        for (unsigned i = 0; i < 3u; i++) {
            L0[i] = -L0[i];
            /* the table's lever from the tool tip, q + T_B 0 = q + P_B - R_B P_B */
            L1[i] = (float)((p[i] >> 1) - (pv1[i] >> 1)) * MM_PER_HALF_NM + (P0[i] + L0[i]);
            v0[i] -= v1[i];
        }
        cross_add_f32(w0, L0, 1.0e-3f, v0);
        cross_add_f32(w1, L1, -1.0e-3f, v0);
        for (unsigned i = 0; i < 3u; i++) {
            w0[i] -= w1[i];
        }
        sign = 1.0f;
    } else {
        /* R0 of the inner axis' twist; g = P0 - P1 = -offset */
        rotate_f32(k0, c0, s0r, v1, t);
        for (unsigned i = 0; i < 3u; i++) {
            v1[i] = t[i];
            L1[i] = (float)-m5->offset_nm[i] * 1.0e-6f;
        }
        rotate_f32(k0, c0, s0r, w1, t);
        w1[0] = t[0];
        w1[1] = t[1];
        w1[2] = t[2];
        rotate_f32(k0, c0, s0r, L1, t); /* R0 g */
        if (kind == ABBE_KIN_XYZBC_HH) {
            /* L = R0 (P1 - R1 P1 - P0), P1 in L1 (g is in t now) */
            for (unsigned i = 0; i < 3u; i++) {
                L1[i] = (float)pv1[i] * 1.0e-6f;
            }
            rotate_f32(k1, c1, s1r, L1, L0);
            for (unsigned i = 0; i < 3u; i++) {
                L1[i] = L1[i] - L0[i] - P0[i];
            }
            rotate_f32(k0, c0, s0r, L1, L0);
            sign = 1.0f;
        } /* else L0 = q - P0 (above) */
        for (unsigned i = 0; i < 3u; i++) {
            v0[i] += v1[i];
            w0[i] += w1[i];
        }
        cross_add_f32(w0, L0, 1.0e-3f, v0);
        cross_add_f32(w1, t, 1.0e-3f, v0);
    }
    /* the linear axes' orientation error turns the head about q: W_lin x (tip - q), the tip
     * at T_T 0 = P0 + L0 from q in the head (kinds 3, 4) */
    if (kind != ABBE_KIN_XYZAB_TDR) {
        for (unsigned i = 0; i < 3u; i++) {
            t[i] = P0[i] + L0[i];
        }
        cross_add_f32(out->orient_urad, t, 1.0e-3f, out->error_um);
    }
    /* five-axis squareness, lever from its reference point: mm x urad = nm */
    const float sy = (float)((p[1] >> 1) - (m5->square_ref_nm[1] >> 1)) * MM_PER_HALF_NM;
    const float sz = (float)((p[2] >> 1) - (m5->square_ref_nm[2] >> 1)) * MM_PER_HALF_NM;
    const float qs = URAD_PER_Q36 * 1.0e-3f;
    out->error_um[0] += (sy * (float)m5->squareness_q36[0] - sz * (float)m5->squareness_q36[1]) * qs;
    out->error_um[1] -= sz * (float)m5->squareness_q36[2] * qs;
    for (unsigned i = 0; i < 3u; i++) {
        out->error_um[i] += sign * v0[i];
        out->orient_urad[i] += sign * w0[i];
    }
}
#endif

static void refuse(abbe_five_error_f32_t *out)
{
    for (unsigned i = 0; i < 3u; i++) {
        out->error_um[i] = 0.0f;
        out->orient_urad[i] = 0.0f;
    }
    out->flags = 0;
}

abbe_status_t abbe_five_eval_f32_linear(const abbe_model_t *m, const float pos_mm[3], const float angle_deg[2],
                                        const float dir_state[3], const float temp_c[3], abbe_five_error_f32_t *out,
                                        int32_t at[ABBE_FIVE_AT])
{
    int32_t *p = at, *udeg = &at[ABBE_AXES];
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
    out->flags = flags;
    return ABBE_OK;
}

void abbe_five_eval_f32_rotary(const abbe_five_model_t *m5, const int32_t p[3], const int32_t udeg[2],
                               abbe_five_error_f32_t *out)
{
    if (m5 == NULL) {
        /* a 3-axis model under the compensator: its position error only */
        out->orient_urad[0] = out->orient_urad[1] = out->orient_urad[2] = 0.0f;
#if !defined(ABBE_NO_FIVE_KINDS)
    } else if (m5->kind >= ABBE_KIN_XYZBC_HH) {
        add_chain_f32(m5, p, udeg, out);
#endif
    } else if (m5->kind != ABBE_KIN_NONE) {
        add_rotary_f32(m5, p, udeg, out);
    }
}

abbe_status_t abbe_five_error_eval_f32(const abbe_five_model_t *m5, const abbe_five_input_f32_t *in,
                                       abbe_five_error_f32_t *out)
{
    if (m5 == NULL || in == NULL || out == NULL) {
        return ABBE_E_ARG;
    }
    int32_t at[ABBE_FIVE_AT];
    const abbe_status_t st =
        abbe_five_eval_f32_linear(&m5->linear, in->pos_mm, in->angle_deg, in->dir_state, in->temp_c, out, at);
    if (st == ABBE_OK) {
        abbe_five_eval_f32_rotary(m5, at, &at[ABBE_AXES], out);
    }
    return st;
}
