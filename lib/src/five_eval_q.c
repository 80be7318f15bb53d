/* abbe: five-axis tool tip error, fixed point (abbe/five_axis.h).
 *
 * The same first-order model as five_eval_f32.c, in integers:
 *   levers        2 nm (int64; an int32 difference of halved positions, exact to 1 nm)
 *   rotations     Q30 sin/cos (abbe_sincos_q30), harmonics by rotation
 *   w (angles)    2^-36 rad, |w_i| <= 4 x 2^28 (the loader's caps)
 *   d (positions) 2^-8 nm, rotated by the tilt in 2^-4 nm (|d| < 2^35 q8)
 * Bounds of every intermediate: docs/numerics.md, "Five-axis evaluation".
 */
#include "internal.h"

#define Q30 30u

/* (c, s) rotation of v about machine axis k (inverse: by -s), Q30, rounded. */
static void rotate_q(unsigned k, int32_t c, int32_t s, int inverse, int64_t v[3])
{
    const unsigned j = (k + 1u) % 3u, l = (k + 2u) % 3u;
    const int64_t sn = inverse ? -(int64_t)s : s;
    const int64_t vj = v[j], vl = v[l];
    v[j] = abbe_shr_round(c * vj - sn * vl, Q30);
    v[l] = abbe_shr_round(sn * vj + c * vl, Q30);
}

#define MAC(acc, coef, v) acc = abbe_smlal(acc, (coef), (v))

/* The error motions of an axis at its angle (c, s), Q30: m in 2^-8 nm (X, Y,
 * Z) and 2^-36 rad (A, B, C); sum |coef| x 2^30 <= 2^62 (loader caps). The
 * six-component case keeps its accumulators in registers. */
ABBE_NOINLINE static void motions_q(const abbe_rotary_model_t *ax, int32_t c, int32_t s, int64_t d[3], int64_t w[3])
{
    const unsigned n = ax->n_comp;
    const uint8_t *row = ax->coef_q;
    int32_t sk = s, ck = c;
    const int64_t half = (int64_t)1 << (Q30 - 1u); /* the final shift's rounding */
    if (n == ABBE_MOTIONS) {
        int64_t a0 = half, a1 = half, a2 = half, a3 = half, a4 = half, a5 = half;
        for (unsigned k = 0; k < ax->harmonics; k++, row += 48u) {
#define ROW(acc, i) MAC(acc, abbe_ld_i32(row + 4u * (i)), sk); MAC(acc, abbe_ld_i32(row + 24u + 4u * (i)), ck)
            ROW(a0, 0u); ROW(a1, 1u); ROW(a2, 2u); ROW(a3, 3u); ROW(a4, 4u); ROW(a5, 5u);
#undef ROW
            const int32_t sn = (int32_t)abbe_shr_round((int64_t)sk * c + (int64_t)ck * s, Q30);
            ck = (int32_t)abbe_shr_round((int64_t)ck * c - (int64_t)sk * s, Q30);
            sk = sn;
        }
        d[0] = a0 >> Q30; d[1] = a1 >> Q30; d[2] = a2 >> Q30;
        w[0] = a3 >> Q30; w[1] = a4 >> Q30; w[2] = a5 >> Q30;
        return;
    }
    int64_t acc[ABBE_MOTIONS];
    for (unsigned i = 0; i < ABBE_MOTIONS; i++) {
        acc[i] = half;
    }
    for (unsigned k = 0; k < ax->harmonics; k++) {
        for (unsigned col = 0; col < n; col++) {
            MAC(acc[col], abbe_ld_i32(row + 4u * col), sk);
            MAC(acc[col], abbe_ld_i32(row + 4u * (n + col)), ck);
        }
        row += 8u * n;
        const int32_t sn = (int32_t)abbe_shr_round((int64_t)sk * c + (int64_t)ck * s, Q30);
        ck = (int32_t)abbe_shr_round((int64_t)ck * c - (int64_t)sk * s, Q30);
        sk = sn;
    }
    for (unsigned i = 0; i < 3u; i++) {
        d[i] = ax->column[i] == 0xFFu ? 0 : acc[ax->column[i]] >> Q30;
        w[i] = ax->column[3u + i] == 0xFFu ? 0 : acc[ax->column[3u + i]] >> Q30;
    }
}

/* An axis' twist (five_eval_f32.c) for a lever L (2 nm units): d in 2^-8 nm,
 * w in 2^-36 rad. */
ABBE_NOINLINE static void twist_q(const abbe_rotary_model_t *ax, int32_t c, int32_t s, const int64_t L[3], int64_t d[3],
                                  int64_t w[3])
{
    motions_q(ax, c, s, d, w); /* d = m_trans, w = m_rot */
    /* + (I - R) phi, (I - R) delta, componentwise (no component along the axis k) */
    const unsigned k = ax->dir, j = (k + 1u) % 3u, l = (k + 2u) % 3u;
    const int64_t pj = ax->phi_q36[j], pl = ax->phi_q36[l], dj = ax->delta_q8[j], dl = ax->delta_q8[l];
    w[j] += pj - abbe_shr_round(c * pj - s * pl, Q30);
    w[l] += pl - abbe_shr_round(s * pj + c * pl, Q30);
    d[j] += dj - abbe_shr_round(c * dj - s * dl, Q30);
    d[l] += dl - abbe_shr_round(s * dj + c * dl, Q30);
    w[ax->dir] += ax->zero_q36;
    /* w x L: 2^-36 rad x 2 nm = 2^-35 nm, each product < 2^61.5; -> 2^-8 nm */
    d[0] += abbe_shr_round(w[1] * L[2] - w[2] * L[1], 27u);
    d[1] += abbe_shr_round(w[2] * L[0] - w[0] * L[2], 27u);
    d[2] += abbe_shr_round(w[0] * L[1] - w[1] * L[0], 27u);
}

/* pos (2^-4 nm) and rot (2^-36 rad) minus the rotary axes' twists, plus the
 * five-axis squareness. Out of line: its frame and the linear evaluation's are
 * never on the stack together. */
ABBE_NOINLINE static void add_rotary_q(const abbe_five_model_t *m5, const int32_t pos_nm[3],
                                       const int32_t angle_udeg[2], int64_t pos[3], int64_t rot[3])
{
    const abbe_rotary_model_t *tilt = &m5->rotary[0], *table = &m5->rotary[1];
    int32_t st, ct, sc, cc;
    abbe_sincos_q30(abbe_udeg_phase_q32(angle_udeg[0]), &st, &ct);
    abbe_sincos_q30(abbe_udeg_phase_q32(angle_udeg[1]), &sc, &cc);
    int64_t L[3], d[3], w[3];
    /* the table axis C at the point before the tilt's rotation: lever R_t^T (q - P_t) + offset */
    for (unsigned i = 0; i < 3u; i++) {
        L[i] = (pos_nm[i] >> 1) - (m5->tilt_pivot_nm[i] >> 1);
    }
    rotate_q(tilt->dir, ct, st, 1, L);
    for (unsigned i = 0; i < 3u; i++) {
        L[i] += m5->offset_nm[i] >> 1;
    }
    twist_q(table, cc, sc, L, d, w);
    for (unsigned i = 0; i < 3u; i++) {
        d[i] = abbe_shr_round(d[i], 4u); /* 2^-4 nm: |d| < 2^31, the rotation's products < 2^61 */
    }
    rotate_q(tilt->dir, ct, st, 0, d);
    rotate_q(tilt->dir, ct, st, 0, w);
    for (unsigned i = 0; i < 3u; i++) {
        pos[i] -= d[i];
        rot[i] -= w[i];
    }
    /* the tilt axis: lever q - P_t */
    for (unsigned i = 0; i < 3u; i++) {
        L[i] = (pos_nm[i] >> 1) - (m5->tilt_pivot_nm[i] >> 1);
    }
    twist_q(tilt, ct, st, L, d, w);
    for (unsigned i = 0; i < 3u; i++) {
        pos[i] -= abbe_shr_round(d[i], 4u);
        rot[i] -= w[i];
    }
    /* five-axis squareness, lever y, z from the C centre: 2 nm x 2^-36 rad -> 2^-4 nm */
    const int64_t y = (pos_nm[1] >> 1) - (m5->rot_point_nm[1] >> 1), z = (pos_nm[2] >> 1) - (m5->rot_point_nm[2] >> 1);
    pos[0] += abbe_shr_round(y * m5->squareness_q36[0] - z * m5->squareness_q36[1], 31u);
    pos[1] -= abbe_shr_round(z * m5->squareness_q36[2], 31u);
}

uint32_t abbe_five_eval_q_core(const abbe_five_model_t *m5, const int32_t pos_nm[3], const int32_t angle_udeg[2],
                               const int32_t dir_q30[3], const int32_t temp_mdegc[3],
                               int32_t values[ABBE_AXES * ABBE_TERMS], int32_t error_nm[3], int32_t orient_nrad[3])
{
    uint32_t flags = abbe_eval_q_core(&m5->linear, pos_nm, dir_q30, temp_mdegc, values, error_nm);
    /* orientation, 2^-36 rad: eps_Z - eps_X - eps_Y (term values in 2^-35 rad) */
    int64_t rot[3], pos[3]; /* pos: 2^-4 nm */
    for (unsigned c = 0; c < 3u; c++) {
        rot[c] = 2 * ((int64_t)values[2 * ABBE_TERMS + 3 + c] - values[3 + c] - values[ABBE_TERMS + 3 + c]);
        pos[c] = (int64_t)error_nm[c] * 16;
    }
    if (m5->kind != ABBE_KIN_NONE) {
        add_rotary_q(m5, pos_nm, angle_udeg, pos, rot);
    }
    for (unsigned i = 0; i < 3u; i++) {
        error_nm[i] = abbe_sat_i32(abbe_shr_round(pos[i], 4u), &flags);
        /* 2^-36 rad -> nrad: x 10^9 / 2^36 = x 1953125 / 2^27 (|rot| < 2^33: product < 2^54) */
        orient_nrad[i] = abbe_sat_i32(abbe_shr_round(rot[i] * 1953125, 27u), &flags);
    }
    return flags;
}

abbe_status_t abbe_five_error_eval_q(const abbe_five_model_t *m5, const abbe_five_input_q_t *in,
                                     abbe_five_error_q_t *out)
{
    if (m5 == NULL || in == NULL || out == NULL) {
        return ABBE_E_ARG;
    }
    int32_t values[ABBE_AXES * ABBE_TERMS];
    out->flags = abbe_five_eval_q_core(m5, in->pos_nm, in->angle_udeg, in->dir_state_q30, in->temp_mdegc, values,
                                       out->error_nm, out->orient_nrad);
    return ABBE_OK;
}
