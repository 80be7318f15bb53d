/* abbe: five-axis tool tip error, fixed point (abbe/five_axis.h).
 *
 * The same first-order model as five_eval_f32.c, in integers, rearranged so
 * that every product is one 32 x 32 -> 64 multiply (SMULL / SMLAL on a
 * Cortex-M): with R_t the tilt's rotation, q - P_t the tilt's lever Lt and
 * the C axis' lever Lc = R_t^T Lt + offset,
 *   R_t d_C = R_t v_C + W_C x (Lt + R_t offset),  W_C = R_t w_C,
 *   v = (I - R) delta + m_trans   (rotations keep cross products), so
 *   E -= R_t v_C + v_t + W_C x (Lt + R_t offset) + w_t x Lt,
 *   W -= W_C + w_t.
 * Units:
 *   levers        2 nm, int32 (an int32 difference of halved positions, exact to 1 nm)
 *   rotations     Q30 sin/cos (abbe_sincos_q30), harmonics by rotation
 *   w (angles)    2^-36 rad, |w_i| <= 2^30 per axis (the loader's caps: 2 |phi| + E0 + sum |m|)
 *   v (positions) 2^-8 nm summed exactly, then 2^-4 nm (|v| < 2^29)
 *   w x L         2^-35 nm, each component's two products of an axis < 2^62, -> 2^-4 nm
 * Bounds of every intermediate: docs/numerics.md, "Five-axis evaluation".
 */
#include "internal.h"

#define Q30 30u

/* (a b - c d) / 2^30, rounded: Q30 rotations of int32 values, |result| < 2^31
 * by the callers' bounds; two SMLALs on a Cortex-M (c d is never -2^31 x -2^31:
 * |sin|, |cos| <= 2^30). */
static ABBE_ALWAYS_INLINE int64_t rot_q30(int32_t a, int32_t b, int32_t c, int32_t d)
{
    return abbe_smlal(abbe_smlal((int64_t)1 << (Q30 - 1u), a, b), -c, d) >> Q30;
}

/* The error motions of an axis at its angle (c, s), rounded: m_trans (X, Y,
 * Z) in 2^-4 nm (|.| <= 2^28: sum |coef| <= 2^32 of 2^-8 nm), m_rot (A, B, C)
 * in 2^-36 rad, into trans and rot. The harmonics' sin k t, cos k t (Q30, by rotation) are made
 * once, into basis (the caller's working memory: the compensator's scratch);
 * then three components per pass over them (a fitted axis: two passes), the
 * int64 sums in registers; sum |coef| x 2^30 <= 2^62 (loader caps).
 * The contract (docs/proofs.md, "Five-axis: the loader's caps"): each motion within
 * +/-(2^28 + 4), for every table the loader accepts (sum |c| <= 2^32 linear, 2^28
 * angular, times the basis rows' bound 2^30 + 16: WP, tests/proofs/terms_q_l1.c
 * rot_trans_q / rot_ang_q; checked on the body by Eva in eval_five_any_q, used as
 * the function by eval_five_any_q_caps). */
/*@ requires layout: ax->harmonics <= 8 && ax->n_comp <= 6;
    requires \valid(basis + (0 .. 15)) && \valid(trans + (0 .. 2)) && \valid(rot + (0 .. 2));
    assigns basis[0 .. 15], trans[0 .. 2], rot[0 .. 2]
        \from c, s, ax->harmonics, ax->n_comp, ax->column[0 .. 5], ax->coef_q[0 .. 4 * 96 - 1];
    ensures init: \initialized(trans + (0 .. 2)) && \initialized(rot + (0 .. 2));
    ensures motion_x: -0x10000004 <= trans[0] <= 0x10000004;
    ensures motion_y: -0x10000004 <= trans[1] <= 0x10000004;
    ensures motion_z: -0x10000004 <= trans[2] <= 0x10000004;
    ensures motion_a: -0x10000004 <= rot[0] <= 0x10000004;
    ensures motion_b: -0x10000004 <= rot[1] <= 0x10000004;
    ensures motion_c: -0x10000004 <= rot[2] <= 0x10000004;
 */
ABBE_NOINLINE static void motions_q(const abbe_rotary_model_t *ax, int32_t c, int32_t s, int32_t *basis,
                                    int32_t trans[3], int32_t rot[3])
{
    const unsigned n = ax->n_comp, rows = 2u * ax->harmonics; /* 0 without components (the loader) */
    if (rows == 0u) { /* no error motions (location errors only) */
        trans[0] = trans[1] = trans[2] = rot[0] = rot[1] = rot[2] = 0;
        return;
    }
    const int32_t ns = -s;
    int32_t sk = s, ck = c;
    for (unsigned r = 0; r < rows; r += 2u) {
        /* harmonic r / 2 + 1 (the rotation of basis_q.h's dot2_q30 from abbe_sincos_q30's pair):
         * within 2^30 + 16 for every phase, enumerated (tests/proofs/hypotheses.c) */
        /*@ assert sincos_range: -0x40000010 <= sk <= 0x40000010 && -0x40000010 <= ck <= 0x40000010; */
        basis[r] = sk;
        basis[r + 1u] = ck;
        /* next harmonic: rotate by the fundamental, rounded (one SMULL, one SMLAL each).
         * (c, s) is abbe_sincos_q30's pair of the joint angle and this is
         * basis_q.h's dot2_q30 (the same int64 sums): harmonics 2..9 of every
         * phase stay within +/-(2^30 + 16), the hypothesis sincos_range that
         * tests/proofs/hypotheses.c checks on these int64 values, so their
         * conversions to int32 are in range */
        const int64_t half30 = (int64_t)1 << (Q30 - 1u);
        const int64_t sn_w = abbe_smlal(abbe_smlal(half30, sk, c), ck, s) >> Q30;
        const int64_t cn_w = abbe_smlal(abbe_smlal(half30, ck, c), sk, ns) >> Q30;
        /*@ assert sincos_range: -1073741840 <= sn_w <= 1073741840 && -1073741840 <= cn_w <= 1073741840; */
        ck = (int32_t)cn_w;
        sk = (int32_t)sn_w;
    }
    if (n == ABBE_MOTIONS) {
        /* components g .. g + 2, a harmonic's two rows (sin, cos) per pass; 2^-38 nm -> 2^-4 nm
         * (shift 34), 2^-66 rad -> 2^-36 rad (30) */
#define GROUP(m, g, shift)                                                                                    \
    do {                                                                                                   \
        const int64_t half_ = (int64_t)1 << ((shift) - 1u);                                                \
        int64_t a0 = half_, a1 = half_, a2 = half_;                                                        \
        const uint8_t *row = ax->coef_q + 4u * (g);                                                        \
        for (unsigned r = 0; r < rows; r += 2u, row += 48u) {                                              \
            const int32_t bs = basis[r], bc = basis[r + 1u];                                               \
            a0 = abbe_smlal(a0, abbe_ld_i32_aligned(row), bs);                                             \
            a1 = abbe_smlal(a1, abbe_ld_i32_aligned(row + 4u), bs);                                        \
            a2 = abbe_smlal(a2, abbe_ld_i32_aligned(row + 8u), bs);                                        \
            a0 = abbe_smlal(a0, abbe_ld_i32_aligned(row + 24u), bc);                                       \
            a1 = abbe_smlal(a1, abbe_ld_i32_aligned(row + 28u), bc);                                       \
            a2 = abbe_smlal(a2, abbe_ld_i32_aligned(row + 32u), bc);                                       \
        }                                                                                                  \
        (m)[0] = (int32_t)(a0 >> (shift));                                                                 \
        (m)[1] = (int32_t)(a1 >> (shift));                                                                 \
        (m)[2] = (int32_t)(a2 >> (shift));                                                                 \
    } while (0)
        GROUP(trans, 0u, Q30 + 4u);
        GROUP(rot, 3u, Q30);
#undef GROUP
        return;
    }
    for (unsigned i = 0; i < ABBE_MOTIONS; i++) {
        const unsigned shift = i < 3u ? Q30 + 4u : Q30;
        int64_t acc = (int64_t)1 << (shift - 1u);
        const unsigned col = ax->column[i];
        /* the word's pointer formed where it is read: an absent component's column
         * (0xFF) would point 1020 B on, a row pointer stepped past the last row past
         * the array's end */
        for (unsigned r = 0; col != 0xFFu && r < rows; r++) {
            acc = abbe_smlal(acc, abbe_ld_i32_aligned(ax->coef_q + 4u * (col + r * n)), basis[r]);
        }
        (i < 3u ? trans : rot)[i % 3u] = col != 0xFFu ? (int32_t)(acc >> shift) : 0;
    }
}

/* An axis' twist at its angle (c, s) without the lever: w (2^-36 rad) and
 * v = (I - R) delta + m_trans (2^-4 nm); k the axis it turns about, (j, l)
 * the other two in cyclic order (phi and delta have no component along k).
 * scratch: working memory for the motions. */
static ABBE_ALWAYS_INLINE void twist_q(const abbe_rotary_model_t *ax, unsigned k, unsigned j, unsigned l, int32_t c,
                                       int32_t s_motion, int32_t sr, int32_t *scratch, int32_t v[3], int32_t w[3])
{
    motions_q(ax, c, s_motion, scratch, v, w); /* the motions: functions of the joint angle */
    const int32_t s = sr;                      /* sr: the rotation's sine */
    const int32_t pj = ax->phi_q36[j], pl = ax->phi_q36[l], dj = ax->delta_q8[j], dl = ax->delta_q8[l];
    w[k] += ax->zero_q36;
    w[j] += (int32_t)(pj - rot_q30(c, pj, s, pl));
    w[l] += (int32_t)(pl - rot_q30(s, pj, -c, pl));
    v[j] += (int32_t)abbe_shr_round(dj - rot_q30(c, dj, s, dl), 4u);
    v[l] += (int32_t)abbe_shr_round(dl - rot_q30(s, dj, -c, dl), 4u);
}

#if (ABBE_FIVE_KIND_MASK & 0x06u) != 0u
/* The rotary axes' share, added to the linear axes' error (error_nm, nm) and
 * orientation (orient: 2^-36 rad in, |.| < 2^30), and the five-axis
 * squareness; then the outputs rounded to nm and nrad (saturated, flagged).
 * Positions in 2^-4 nm here (int64). scratch: 16 words of working memory
 * (the linear term values, used up). Out of line: its frame and the linear
 * evaluation's are never on the stack together. */
ABBE_NOINLINE static uint32_t add_rotary_q(const abbe_five_model_t *m5, const int32_t pos_nm[3],
                                           const int32_t angle_udeg[2], int32_t *scratch, int32_t error_nm[3],
                                           int32_t orient[3], uint32_t flags)
{
    const abbe_rotary_model_t *tilt = &m5->rotary[0], *table = &m5->rotary[1];
    const unsigned k = tilt->dir, j = k + 1u, l = k == 0u ? 2u : 0u; /* the tilt turns about X or Y */
    int32_t st, ct, sc, cc;
    abbe_sincos_q30(abbe_udeg_phase_q32(angle_udeg[0]), &st, &ct);
    abbe_sincos_q30(abbe_udeg_phase_q32(angle_udeg[1]), &sc, &cc);
    int32_t v[3], w[3], vt[3], wt[3], Ro[3];
    /* the table axis C (about Z), then R_t of its v and w */
    twist_q(table, 2u, 0u, 1u, cc, sc, sc, scratch, v, w);
    twist_q(tilt, k, j, l, ct, st, st, scratch, vt, wt);
    const int32_t vj = v[j], wj = w[j];
    v[j] = (int32_t)rot_q30(ct, vj, st, v[l]);
    v[l] = (int32_t)rot_q30(st, vj, -ct, v[l]);
    /* the turn keeps the norm (docs/proofs.md, "Five-axis: the loader's caps"): with
     * |(wj, w_l)|^2 <= 5 x 2^58 + 2^35 (the caps: |wj| <= 2^30 + 8, |w_l| <= 2^29 + 8) and
     * sin^2 + cos^2 <= 2^60 + 2^33 (every phase, enumerated), each turned component is
     * within 9 x 2^27 (WP: tests/proofs/turn_q.c) */
    /*@ assert turn_vector: (integer)wj * wj + (integer)w[l] * w[l] <= 0x1400000800000000; */
    w[j] = (int32_t)rot_q30(ct, wj, st, w[l]);
    w[l] = (int32_t)rot_q30(st, wj, -ct, w[l]);
    /*@ assert turned_w: -0x48000000 <= w[j] <= 0x48000000 && -0x48000000 <= w[l] <= 0x48000000; */
    /* R_t offset, 2 nm (no component along the tilt axis: the loader), |.| < 2^29.5 */
    const int32_t oj = m5->offset_nm[j] >> 1, ol = m5->offset_nm[l] >> 1;
    Ro[k] = 0;
    Ro[j] = (int32_t)rot_q30(ct, oj, st, ol);
    Ro[l] = (int32_t)rot_q30(st, oj, -ct, ol);
    /* per component i (i1, i2 the next two cyclically), one copy of the code (flash,
     * bench/results.md section 11): the tilt's lever Lt = q - P_t in 2 nm (an int32
     * difference of halved positions), W_C x (Lt + R_t offset) (four products < 2^61.5,
     * two < 2^60) and w_t x Lt, 2^-35 nm -> 2^-4 nm */
    for (unsigned i = 0; i < 3u; i++) {
        const unsigned i1 = i == 2u ? 0u : i + 1u, i2 = i == 0u ? 2u : i - 1u;
        const int32_t Li1 = (pos_nm[i1] >> 1) - (m5->tilt_pivot_nm[i1] >> 1);
        const int32_t Li2 = (pos_nm[i2] >> 1) - (m5->tilt_pivot_nm[i2] >> 1);
        /* five-axis squareness, lever y, z from the C centre: 2 nm x 2^-36 rad -> 2^-4 nm
         * (dX: y S_xy - z S_xz, dY: -z S_yz; formed here, where it is added: fewer values
         * live across the loop, the stack of bench/results.md section 11) */
        int64_t sq = 0;
        if (i < 2u) {
            const int32_t z = (pos_nm[2] >> 1) - (m5->rot_point_nm[2] >> 1);
            const int32_t y = i == 0u ? (pos_nm[1] >> 1) - (m5->rot_point_nm[1] >> 1) : 0;
            sq = abbe_smlal(abbe_smlal((int64_t)1 << 30, y, m5->squareness_q36[0]), -z,
                            m5->squareness_q36[i == 0u ? 1u : 2u]) >> 31;
        }
        int64_t c_table = abbe_smlal(abbe_smlal((int64_t)1 << 30, w[i1], Li2), -w[i2], Li1);
        c_table = abbe_smlal(abbe_smlal(c_table, w[i1], Ro[i2]), -w[i2], Ro[i1]) >> 31;
        const int64_t c_tilt = abbe_smlal(abbe_smlal((int64_t)1 << 30, wt[i1], Li2), -wt[i2], Li1) >> 31;
        const int64_t pos = (int64_t)error_nm[i] * 16 + sq - ((int64_t)v[i] + vt[i] + c_table + c_tilt);
        error_nm[i] = abbe_sat_i32(abbe_shr_round(pos, 4u), &flags);
    }
    for (unsigned i = 0; i < 3u; i++) { /* apart: fewer values live in the loop above (stack) */
        const int64_t rot = (int64_t)orient[i] - w[i] - wt[i];
        /* 2^-36 rad -> nrad: x 10^9 / 2^36 = x 1953125 / 2^27 (|rot| < 2^32: product < 2^53) */
        orient[i] = abbe_sat_i32(abbe_shr_round(rot * 1953125, 27u), &flags);
    }
    return flags;
}
#endif

#if !defined(ABBE_NO_FIVE_KINDS)
/* a = Rot_k(t) a in place, Q30 (c, s), rounded; inlined (bench/results.md section 11: the
 * calls, not the products, were most of the other kinds' instructions). */
static ABBE_ALWAYS_INLINE void rotate_q(unsigned k, int32_t c, int32_t s, int32_t a[3])
{
    const unsigned j = k == 2u ? 0u : k + 1u, l = k == 0u ? 2u : k - 1u;
    const int32_t x = a[j], y = a[l];
    a[j] = (int32_t)rot_q30(c, x, s, y);
    a[l] = (int32_t)rot_q30(s, x, -c, y);
}

/* rot_q30's sum before its shift: a b - c d + 2^29 (two SMLALs) */
static ABBE_ALWAYS_INLINE int64_t rot_sum_q30(int32_t a, int32_t b, int32_t c, int32_t d)
{
    return abbe_smlal(abbe_smlal((int64_t)0x20000000, a, b), -c, d);
}

/* The high word of an int64 plus 2^29 (mod 2^32): below 2^30 iff the int64 is within
 * [-2^61, 2^61), i.e. iff the int64 >> 30 is within int32 */
static ABBE_ALWAYS_INLINE uint32_t hi_offset_q(int64_t v)
{
    return (uint32_t)((uint64_t)v >> 32) + 0x20000000u;
}

/* acc >> 30 saturated to int32 (abbe_sat_i32's value and flag): its low word where it is
 * within int32, else the bound of acc's sign, flagged */
ABBE_COLD static int32_t saturate_q(int64_t acc, uint32_t *flags)
{
    int32_t v = abbe_u32_to_i32((acc < 0) ? 0x80000000u : 0x7FFFFFFFu); /* INT32_MIN, INT32_MAX */
    if (hi_offset_q(acc) < 0x40000000u) {
        v = abbe_u32_to_i32((uint32_t)((uint64_t)acc >> Q30));
    } else {
        *flags |= ABBE_FLAG_SATURATED;
    }
    return v;
}

/* rotate_q with each turned component saturated to int32 (ABBE_FLAG_SATURATED): the
 * chain kinds' pairs whose bound is their norm, not each component's (chain_q: kind 3's
 * head lever, kinds 3 and 5's inner twist v1 + w1 x g). On every table the loader accepts
 * each turned component is below 2^31 (their norms: docs/numerics.md, "Five-axis
 * evaluation"), so the result is rotate_q's, bit for bit, and the flag is never set; beyond
 * (a model not from the loader) it is defined and flagged where the int32 conversion would
 * wrap. The test is on rot_q30's two int64 sums before the shift: acc >> 30 is within
 * int32 iff acc is within [-2^61, 2^61), i.e. its high word within [-2^29, 2^29); both high
 * words offset by 2^29 and or-ed, one unsigned test (instructions: bench/results.md
 * section 11); the values are then the low words of the shifted sums, the saturation out
 * of line and cold (flash; the common path laid out straight); docs/proofs.md, "The chain
 * kinds' turned pairs". */
static ABBE_ALWAYS_INLINE void rotate_sat_q(unsigned k, int32_t c, int32_t s, int32_t a[3], uint32_t *flags)
{
    const unsigned j = (k == 2u) ? 0u : (k + 1u);
    const unsigned l = (k == 0u) ? 2u : (k - 1u);
    const int64_t x = rot_sum_q30(c, a[j], s, a[l]);
    const int64_t y = rot_sum_q30(s, a[j], -c, a[l]);
    if ((hi_offset_q(x) | hi_offset_q(y)) < 0x40000000u) { /* both within int32 after the shift */
        a[j] = abbe_u32_to_i32((uint32_t)((uint64_t)x >> Q30));
        a[l] = abbe_u32_to_i32((uint32_t)((uint64_t)y >> Q30));
    } else {
        a[j] = saturate_q(x, flags);
        a[l] = saturate_q(y, flags);
    }
}

/* Kind 3's R1 P1 (P1 = tilt_pivot, halved) as rotate_q's values mod 2^32, for the head
 * lever's sum, which is taken mod 2^32 (hh_lever). Exact for every model: the pair's norm
 * is at most 2^30.5 (halves of int32) and a Q30 turn keeps it to within (1 + 2^-28)
 * (c^2 + s^2 <= 2^60 + 2^33, the hypothesis sincos_norm), so each turned component is
 * within 2^30.5 + 7 < 2^31 and its low word is its value: no test, no saturation, and no
 * signed conversion for Eva to bound (docs/proofs.md, "The chain kinds' turned pairs"). */
static ABBE_ALWAYS_INLINE void rotate_low_q(unsigned k, int32_t c, int32_t s, const int32_t a[3], uint32_t u[3])
{
    const unsigned j = (k == 2u) ? 0u : (k + 1u);
    const unsigned l = (k == 0u) ? 2u : (k - 1u);
    u[k] = (uint32_t)a[k];
    u[j] = (uint32_t)(uint64_t)rot_q30(c, a[j], s, a[l]);
    u[l] = (uint32_t)(uint64_t)rot_q30(s, a[j], -c, a[l]);
}

/* (w x L)_i, w in 2^-36 rad, L in 2 nm, both int32 (two SMLALs): 2^-35 nm -> 2^-4 nm, rounded */
static ABBE_ALWAYS_INLINE int64_t cross32_q(const int32_t w[3], const int32_t L[3], unsigned i)
{
    const unsigned i1 = i == 2u ? 0u : i + 1u, i2 = i == 0u ? 2u : i - 1u;
    return abbe_smlal(abbe_smlal((int64_t)1 << 30, w[i1], L[i2]), -w[i2], L[i1]) >> 31;
}

/* (w x L)_i as cross32_q with an int64 lever (|L| < 2^31.6: the tool tip, kind 4's G) */
static ABBE_ALWAYS_INLINE int64_t cross_q(const int32_t w[3], const int64_t L[3], unsigned i)
{
    const unsigned i1 = i == 2u ? 0u : i + 1u, i2 = i == 0u ? 2u : i - 1u;
    return ((int64_t)w[i1] * L[i2] - (int64_t)w[i2] * L[i1] + ((int64_t)1 << 30)) >> 31;
}

/* Kinds 3-5 (format 1.4): five_eval_f32.c's add_chain_f32 in integers (the same
 * formulas, the inner twist moved to its lever G then turned by R0 or negated; levers in
 * 2 nm, w in 2^-36 rad, v and d in 2^-4 nm; each cross product rounded to 2^-4 nm apart). */
/* A record's twist (twist_q) about its own machine axis: one copy for both records. */
ABBE_NOINLINE static void twist_chain_q(const abbe_rotary_model_t *ax, int32_t c, int32_t s, int32_t sr,
                                        int32_t *scratch, int32_t v[3], int32_t w[3])
{
    const unsigned k = ax->dir;
    twist_q(ax, k, k == 2u ? 0u : k + 1u, k == 0u ? 2u : k - 1u, c, s, sr, scratch, v, w);
}

/* A component of kind 3's head lever before R0: -(g + R1 P1), 2 nm. Within
 * +/-(2^31 - 2^9) on every table the loader accepts (HH_LEVER_L1_CAP: |g_j| + |(R1 P1)_j|
 * <= (|offset|_1 + |P1|_1) / 2 + 2), so the sum taken mod 2^32 is the sum (as the loader's
 * tilt_pivot_nm): defined for every operand, where an int32 sum's range would rest on the
 * cap, which relates g and P1 (both from rot_point and offset) as an interval analysis
 * cannot (docs/proofs.md, "Five-axis: any layout"). The same instructions as the int32
 * sum (a clamp in int64 was 132 B of flash, Cortex-M4F -O2). */
static ABBE_ALWAYS_INLINE int32_t hh_lever(int32_t g, uint32_t u)
{
    return abbe_u32_to_i32(0u - ((uint32_t)g + u));
}

/* One kind's geometry, straight-line (kind, k0 = record 0's axis and k1 = record 1's are
 * constants where it is inlined: the loader fixes them per kind): the position error d
 * (2^-4 nm) the chain adds before the kind's sign, w1 turned (R0 w1, kinds 3, 5) or negated
 * (kind 4), and the tool tip from q (2 nm, kinds 3, 4). v1, w1 are used up. Ranges:
 * |rot_point|, |offset| < 2^30 nm (the loader), so halves and their differences fit an
 * int32 (|g| < 2^30.6, kind 4's G < 2^31), the inner twist v1 + w1 x g too (|v1| < 2^29,
 * |w1 x g| < 2^30.6); the outer lever L: kind 5 q - P0 < 2^30.6, kind 4 R0 P0 < 2^29.5,
 * kind 3 R0 (g + R1 P1), whose components are below |g| + |P1| / 2, i.e. below 2^31
 * (2 nm) while |P0 - P1| + |P1| < 4.29 m: the loader refuses kind 3 tables beyond it
 * (HH_LEVER_L1_CAP, model_load_rotary.h: the components' magnitudes summed, ABBE_E_RANGE). */
static ABBE_ALWAYS_INLINE void chain_q(const abbe_five_model_t *m5, const int32_t pos_nm[3], unsigned kind,
                                       unsigned k0, unsigned k1, int32_t c0, int32_t s0r, int32_t c1, int32_t s1r,
                                       const int32_t v0[3], const int32_t w0[3], int32_t v1[3], int32_t w1[3],
                                       int64_t d[3], int64_t tip[3], uint32_t *flags)
{
    int32_t H0[3], L[3], G[3];
    int64_t in1[3];
    const int32_t *pv0 = kind == ABBE_KIN_XYZBC_HT ? m5->offset_nm : m5->rot_point_nm;
    H0[0] = pv0[0] >> 1; /* P0, 2 nm */
    H0[1] = pv0[1] >> 1;
    H0[2] = pv0[2] >> 1;
    if (kind == ABBE_KIN_XYZBC_HT) {
        /* G = q - P_C + P_B (halves: |q| <= 2^30, |P| <= 2^29, so |G| < 2^31); the head B's
         * lever L0 = -R_B P_B */
        G[0] = (pos_nm[0] >> 1) - (m5->rot_point_nm[0] >> 1) + H0[0];
        G[1] = (pos_nm[1] >> 1) - (m5->rot_point_nm[1] >> 1) + H0[1];
        G[2] = (pos_nm[2] >> 1) - (m5->rot_point_nm[2] >> 1) + H0[2];
        L[0] = -H0[0];
        L[1] = -H0[1];
        L[2] = -H0[2];
        rotate_q(k0, c0, s0r, L);
    } else {
        /* g = P0 - P1 (|P1| < 2^31: |g| < 2^30.6) */
        G[0] = H0[0] - (m5->tilt_pivot_nm[0] >> 1);
        G[1] = H0[1] - (m5->tilt_pivot_nm[1] >> 1);
        G[2] = H0[2] - (m5->tilt_pivot_nm[2] >> 1);
        if (kind == ABBE_KIN_XYZBC_HH) {
            /* L = -R0 (g + R1 P1), P1 = tilt_pivot */
            const int32_t P1[3] = {m5->tilt_pivot_nm[0] >> 1, m5->tilt_pivot_nm[1] >> 1, m5->tilt_pivot_nm[2] >> 1};
            uint32_t u[3];
            rotate_low_q(k1, c1, s1r, P1, u); /* |u| <= 2^30.5: halves of int32, mod 2^32 */
            L[0] = hh_lever(G[0], u[0]);
            L[1] = hh_lever(G[1], u[1]);
            L[2] = hh_lever(G[2], u[2]);
            rotate_sat_q(k0, c0, s0r, L, flags); /* |L| <= |g| + |P1| < 2^31: the norm (cap) */
        } else { /* under the workpiece: L = q - P0, an int32 difference of halved positions */
            L[0] = (pos_nm[0] >> 1) - H0[0];
            L[1] = (pos_nm[1] >> 1) - H0[1];
            L[2] = (pos_nm[2] >> 1) - H0[2];
        }
    }
    /* the inner twist at its lever, v1 + w1 x G, 2^-4 nm (SMLALs: |w1| <= 2^30, |G| < 2^31) */
    in1[0] = (int64_t)v1[0] + cross32_q(w1, G, 0u);
    in1[1] = (int64_t)v1[1] + cross32_q(w1, G, 1u);
    in1[2] = (int64_t)v1[2] + cross32_q(w1, G, 2u);
    if (kind == ABBE_KIN_XYZBC_HT) {
        w1[0] = -w1[0];
        w1[1] = -w1[1];
        w1[2] = -w1[2];
        in1[0] = -in1[0];
        in1[1] = -in1[1];
        in1[2] = -in1[2];
    } else {
        v1[0] = (int32_t)in1[0];
        v1[1] = (int32_t)in1[1];
        v1[2] = (int32_t)in1[2];
        rotate_sat_q(k0, c0, s0r, v1, flags); /* |v1| < 2^29, |w1 x g| < 2^29 + 2^4 */
        rotate_q(k0, c0, s0r, w1); /* each |.| <= 2^30 + 8: turned in range by its intervals */
        in1[0] = v1[0];
        in1[1] = v1[1];
        in1[2] = v1[2];
    }
    d[0] = (int64_t)v0[0] + in1[0] + cross32_q(w0, L, 0u) + cross32_q(w1, L, 0u);
    d[1] = (int64_t)v0[1] + in1[1] + cross32_q(w0, L, 1u) + cross32_q(w1, L, 1u);
    d[2] = (int64_t)v0[2] + in1[2] + cross32_q(w0, L, 2u) + cross32_q(w1, L, 2u);
    /* the tool tip at T_T 0 = P0 + L from q (kinds 3, 4) */
    tip[0] = (int64_t)H0[0] + L[0];
    tip[1] = (int64_t)H0[1] + L[1];
    tip[2] = (int64_t)H0[2] + L[2];
}

ABBE_NOINLINE static uint32_t add_chain_q(const abbe_five_model_t *m5, const int32_t pos_nm[3],
                                          const int32_t angle_udeg[2], int32_t *scratch, int32_t error_nm[3],
                                          int32_t orient[3], uint32_t flags)
{
    const unsigned kind = abbe_five_chain_kind(m5);
    int32_t s0, c0, s1, c1;
    abbe_sincos_q30(abbe_udeg_phase_q32(angle_udeg[m5->slot[0]]), &s0, &c0);
    abbe_sincos_q30(abbe_udeg_phase_q32(angle_udeg[m5->slot[1]]), &s1, &c1);
    const int32_t s0r = m5->sign[0] < 0 ? -s0 : s0, s1r = m5->sign[1] < 0 ? -s1 : s1;
    int32_t v0[3], w0[3], v1[3], w1[3];
    int64_t d[3], tip[3] = {0, 0, 0};
    twist_chain_q(&m5->rotary[0], c0, s0, s0r, scratch, v0, w0);
    twist_chain_q(&m5->rotary[1], c1, s1, s1r, scratch, v1, w1);
    /* the machine axes per kind (the loader's): 3 C, B; 4 B, C; 5 B, A */
    int sign = 1; /* in the head */
    if (ABBE_FIVE_KIND_BUILT(ABBE_KIN_XYZBC_HH) != 0u &&
        (kind == ABBE_KIN_XYZBC_HH || (ABBE_FIVE_CHAIN_MASK & 0x30u) == 0u)) {
        chain_q(m5, pos_nm, ABBE_KIN_XYZBC_HH, 2u, 1u, c0, s0r, c1, s1r, v0, w0, v1, w1, d, tip, &flags);
    } else {
        /* kinds 4 and 5 share record 0's axis (B) and one copy (flash); k1 is kind 3's only */
        int64_t t[3];
        chain_q(m5, pos_nm, kind, 1u, 0u, c0, s0r, c1, s1r, v0, w0, v1, w1, d, t, &flags);
        if (kind == ABBE_KIN_XYZAB_TDR) {
            sign = -1; /* under the workpiece, no tool tip term */
        } else {
            tip[0] = t[0];
            tip[1] = t[1];
            tip[2] = t[2];
        }
    }
    for (unsigned i = 0; i < 3u; i++) {
        /* five-axis squareness, lever y, z from its reference point: 2 nm x 2^-36 rad -> 2^-4 nm */
        int64_t sq = 0;
        if (i < 2u) {
            const int32_t z = (pos_nm[2] >> 1) - (m5->square_ref_nm[2] >> 1);
            const int32_t y = i == 0u ? (pos_nm[1] >> 1) - (m5->square_ref_nm[1] >> 1) : 0;
            sq = abbe_smlal(abbe_smlal((int64_t)1 << 30, y, m5->squareness_q36[0]), -z,
                            m5->squareness_q36[i == 0u ? 1u : 2u]) >> 31;
        }
        /* the linear axes' orientation error turns the head about q: W_lin x tip */
        const int64_t lin = cross_q(orient, tip, i);
        const int64_t pos = (int64_t)error_nm[i] * 16 + sq + lin + (sign > 0 ? d[i] : -d[i]);
        error_nm[i] = abbe_sat_i32(abbe_shr_round(pos, 4u), &flags);
    }
    for (unsigned i = 0; i < 3u; i++) {
        const int64_t W = (int64_t)w0[i] + w1[i];
        const int64_t rot = (int64_t)orient[i] + (sign > 0 ? W : -W);
        orient[i] = abbe_sat_i32(abbe_shr_round(rot * 1953125, 27u), &flags);
    }
    return flags;
}
#endif

uint32_t abbe_five_eval_q_core(const abbe_five_model_t *m5, const int32_t pos_nm[3], const int32_t angle_udeg[2],
                               const int32_t dir_q30[3], const int32_t temp_mdegc[3],
                               int32_t values[ABBE_AXES * ABBE_TERMS], int32_t error_nm[3], int32_t orient_nrad[3])
{
    uint32_t flags = abbe_eval_q_core(&m5->linear, pos_nm, dir_q30, temp_mdegc, values, error_nm);
    /* orientation, 2^-36 rad: eps_Z - eps_X - eps_Y (term values in 2^-35 rad, |.| <= 2^27: the sum fits) */
    for (unsigned c = 0; c < 3u; c++) {
        orient_nrad[c] = 2 * (values[2 * ABBE_TERMS + 3 + c] - values[3 + c] - values[ABBE_TERMS + 3 + c]);
    }
#if !defined(ABBE_NO_FIVE_KINDS)
    if (m5->kind >= ABBE_KIN_XYZBC_HH) {
        return add_chain_q(m5, pos_nm, angle_udeg, values, error_nm, orient_nrad, flags);
    }
#endif
#if (ABBE_FIVE_KIND_MASK & 0x06u) != 0u
    if (m5->kind != ABBE_KIN_NONE) {
        return add_rotary_q(m5, pos_nm, angle_udeg, values, error_nm, orient_nrad, flags);
    }
#endif
    for (unsigned i = 0; i < 3u; i++) {
        orient_nrad[i] = abbe_sat_i32(abbe_shr_round((int64_t)orient_nrad[i] * 1953125, 27u), &flags);
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
