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
        const unsigned col = ax->column[i];
        /* an absent component's column (0xFF) would point 1020 B on: no pointer then */
        const uint8_t *row = col != 0xFFu ? ax->coef_f32 + 4u * col : ax->coef_f32;
        for (unsigned k = 0; col != 0xFFu && k < h; k++, row += 8u * n) {
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
#if (ABBE_FIVE_KIND_MASK & 0x06u) != 0u
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
#endif

#if !defined(ABBE_NO_FIVE_KINDS)
/* a = Rot_k(t) a in place, (c, s) = (cos t, sin t); inlined (bench/results.md section 11:
 * the calls, not the products, were most of the other kinds' instructions). */
static ABBE_ALWAYS_INLINE void rotate_f32(unsigned k, float c, float s, float a[3])
{
    const unsigned j = k == 2u ? 0u : k + 1u, l = k == 0u ? 2u : k - 1u;
    const float x = a[j], y = a[l];
    a[j] = c * x - s * y;
    a[l] = s * x + c * y;
}

/* a x b added to acc times f */
static ABBE_ALWAYS_INLINE void cross_add_f32(const float a[3], const float b[3], float f, float acc[3])
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
 * L = R0 (P1 - R1 P1 - P0) = -R0 (g + R1 P1) in the head (pivots relative to
 * the controlled point; the tool error gets +d, +w). Kind 4: the head's B
 * alone (lever L0 = -R_B P_B, +) and the table's C alone (lever
 * L1 = q - P_C + P_B + L0, -): d = v0 - v1 + w0 x L0 - w1 x L1.
 * Evaluated as (rotations keep cross products: R0 w1 x R0 g = R0 (w1 x g);
 * w1 x L1 = w1 x L0 + w1 x G with G = q - P_C + P_B)
 *   kinds 3, 5: d = v0 + R0 (v1 + w1 x g) + w0 x L + (R0 w1) x L,
 *   kind 4:     d = v0 - (v1 + w1 x G) + w0 x L0 - w1 x L0,
 * i.e. one form: the inner twist moved to its lever G (g, or G), then turned by R0
 * (kinds 3, 5) or negated (kind 4), both twists at the outer lever. */
/* A record's twist (twist_f32) about its own machine axis: one copy for both records
 * (and the trunnions' tilt, add_rotary_f32). */
ABBE_NOINLINE static void twist_chain_f32(const abbe_rotary_model_t *ax, float c, float s, float sr, float vw[6])
{
    const unsigned k = ax->dir;
    twist_f32(ax, k, k == 2u ? 0u : k + 1u, k == 0u ? 2u : k - 1u, c, s, sr, vw);
}

/* (p >> 1) - (pv >> 1): a lever in mm from exact halves (an int32 difference) */
static ABBE_ALWAYS_INLINE float lever_f32(int32_t p, int32_t pv)
{
    return (float)((p >> 1) - (pv >> 1)) * MM_PER_HALF_NM;
}

/* One kind's geometry, straight-line (kind, k0 = record 0's axis and k1 = record 1's are
 * constants where it is inlined: the loader fixes them per kind): the position error d
 * (um) and orientation error W (urad) the chain adds to the tool's, and the
 * tool tip from q (mm, kinds 3, 4). vw1 is used up. */
static ABBE_ALWAYS_INLINE void chain_f32(const abbe_five_model_t *m5, const int32_t p[3], unsigned kind, unsigned k0,
                                         unsigned k1, float c0, float s0r, float c1, float s1r, const float vw0[6],
                                         float vw1[6], float d[3], float W[3], float tip[3])
{
    const float *v0 = vw0, *w0 = vw0 + 3;
    float *v1 = vw1, *w1 = vw1 + 3;
    float G[3], L[3], P0[3];
    const int32_t *pv0 = kind == ABBE_KIN_XYZBC_HT ? m5->offset_nm : m5->rot_point_nm;
    P0[0] = (float)pv0[0] * 1.0e-6f;
    P0[1] = (float)pv0[1] * 1.0e-6f;
    P0[2] = (float)pv0[2] * 1.0e-6f;
    if (kind == ABBE_KIN_XYZBC_HT) {
        /* G = q - P_C + P_B; the head B's lever L0 = -R_B P_B */
        G[0] = lever_f32(p[0], m5->rot_point_nm[0]) + P0[0];
        G[1] = lever_f32(p[1], m5->rot_point_nm[1]) + P0[1];
        G[2] = lever_f32(p[2], m5->rot_point_nm[2]) + P0[2];
        L[0] = -P0[0];
        L[1] = -P0[1];
        L[2] = -P0[2];
        rotate_f32(k0, c0, s0r, L);
    } else {
        /* g = P0 - P1 = -offset */
        G[0] = (float)-m5->offset_nm[0] * 1.0e-6f;
        G[1] = (float)-m5->offset_nm[1] * 1.0e-6f;
        G[2] = (float)-m5->offset_nm[2] * 1.0e-6f;
        if (kind == ABBE_KIN_XYZBC_HH) {
            /* L = -R0 (g + R1 P1), P1 = tilt_pivot */
            float u[3] = {(float)m5->tilt_pivot_nm[0] * 1.0e-6f, (float)m5->tilt_pivot_nm[1] * 1.0e-6f,
                          (float)m5->tilt_pivot_nm[2] * 1.0e-6f};
            rotate_f32(k1, c1, s1r, u);
            L[0] = -(G[0] + u[0]);
            L[1] = -(G[1] + u[1]);
            L[2] = -(G[2] + u[2]);
            rotate_f32(k0, c0, s0r, L);
        } else { /* under the workpiece: L = q - P0 */
            L[0] = lever_f32(p[0], pv0[0]);
            L[1] = lever_f32(p[1], pv0[1]);
            L[2] = lever_f32(p[2], pv0[2]);
        }
    }
    cross_add_f32(w1, G, 1.0e-3f, v1); /* the inner twist at its lever: urad x mm = nm */
    if (kind == ABBE_KIN_XYZBC_HT) {
        W[0] = w0[0] - w1[0];
        W[1] = w0[1] - w1[1];
        W[2] = w0[2] - w1[2];
        d[0] = v0[0] - v1[0];
        d[1] = v0[1] - v1[1];
        d[2] = v0[2] - v1[2];
    } else {
        rotate_f32(k0, c0, s0r, v1);
        rotate_f32(k0, c0, s0r, w1);
        W[0] = w0[0] + w1[0];
        W[1] = w0[1] + w1[1];
        W[2] = w0[2] + w1[2];
        d[0] = v0[0] + v1[0];
        d[1] = v0[1] + v1[1];
        d[2] = v0[2] + v1[2];
    }
    cross_add_f32(W, L, 1.0e-3f, d);
    if (kind == ABBE_KIN_XYZAB_TDR) { /* under the workpiece: the tool error gets -d, -w */
        d[0] = -d[0];
        d[1] = -d[1];
        d[2] = -d[2];
        W[0] = -W[0];
        W[1] = -W[1];
        W[2] = -W[2];
    }
    /* the tool tip at T_T 0 = P0 + L from q in the head (kinds 3, 4) */
    tip[0] = P0[0] + L[0];
    tip[1] = P0[1] + L[1];
    tip[2] = P0[2] + L[2];
}

ABBE_NOINLINE static void add_chain_f32(const abbe_five_model_t *m5, const int32_t p[3], const int32_t udeg[2],
                                        abbe_five_error_f32_t *out)
{
    const unsigned kind = abbe_five_chain_kind(m5);
    float s0, c0, s1, c1;
    abbe_sincos_f32(abbe_udeg_phase_q32(udeg[m5->slot[0]]), &s0, &c0);
    abbe_sincos_f32(abbe_udeg_phase_q32(udeg[m5->slot[1]]), &s1, &c1);
    const float s0r = (float)m5->sign[0] * s0, s1r = (float)m5->sign[1] * s1;
    float vw0[6], vw1[6], d[3], W[3], tip[3];
    twist_chain_f32(&m5->rotary[0], c0, s0, s0r, vw0);
    twist_chain_f32(&m5->rotary[1], c1, s1, s1r, vw1);
    /* the machine axes per kind (the loader's): 3 C, B; 4 B, C; 5 B, A */
    if (ABBE_FIVE_KIND_BUILT(ABBE_KIN_XYZBC_HH) != 0u && kind == ABBE_KIN_XYZBC_HH) {
        chain_f32(m5, p, ABBE_KIN_XYZBC_HH, 2u, 1u, c0, s0r, c1, s1r, vw0, vw1, d, W, tip);
    } else if (ABBE_FIVE_KIND_BUILT(ABBE_KIN_XYZBC_HT) != 0u &&
               (kind == ABBE_KIN_XYZBC_HT || ABBE_FIVE_KIND_BUILT(ABBE_KIN_XYZAB_TDR) == 0u)) {
        chain_f32(m5, p, ABBE_KIN_XYZBC_HT, 1u, 2u, c0, s0r, c1, s1r, vw0, vw1, d, W, tip);
    } else {
        chain_f32(m5, p, ABBE_KIN_XYZAB_TDR, 1u, 0u, c0, s0r, c1, s1r, vw0, vw1, d, W, tip);
    }
    /* the linear axes' orientation error turns the head about q: W_lin x (tip - q) (kinds 3, 4) */
    if (kind != ABBE_KIN_XYZAB_TDR) {
        cross_add_f32(out->orient_urad, tip, 1.0e-3f, out->error_um);
    }
    /* five-axis squareness, lever from its reference point: mm x urad = nm */
    const float sy = lever_f32(p[1], m5->square_ref_nm[1]);
    const float sz = lever_f32(p[2], m5->square_ref_nm[2]);
    const float qs = URAD_PER_Q36 * 1.0e-3f;
    out->error_um[0] += (sy * (float)m5->squareness_q36[0] - sz * (float)m5->squareness_q36[1]) * qs + d[0];
    out->error_um[1] += d[1] - sz * (float)m5->squareness_q36[2] * qs;
    out->error_um[2] += d[2];
    out->orient_urad[0] += W[0];
    out->orient_urad[1] += W[1];
    out->orient_urad[2] += W[2];
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
#if (ABBE_FIVE_KIND_MASK & 0x06u) != 0u
    } else if (m5->kind != ABBE_KIN_NONE) {
        add_rotary_f32(m5, p, udeg, out);
#endif
    } else {
        /* a 3-axis table: no rotary part */
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
