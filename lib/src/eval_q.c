/* abbe: spatial error, fixed point (Eq. 3 + Abbe terms + extras).
 *
 * Term values (terms_q.c): linear L in 2^-6 nm, angular A in 2^-35 rad, int32.
 * Each component of (dX, dY, dZ) is one int64 sum E in 2^-35 nm (nm x 2^-35
 * rad) of products of two int32, one SMLAL each: L x 2^29, and lever x angle
 * sum with the lever split into its int32 parts p, ref and tool offset (p -
 * ref itself can need 33 bits). Angle sums have at most three terms (< 2^29),
 * so every product is below 2^61 and |E| stays below 2^62.25 for any valid
 * table and input (docs/numerics.md). The squareness, in 2^-36 rad, gets its
 * own sum in 2^-36 nm, started from its constant ref part (abbe_model_load),
 * and is halved into E. E starts at the rounding constant: the result in whole
 * nm is E >> 35, below 2^28 nm, so it needs no saturation. The extra terms
 * (backlash with its reversal block, thermal), which can be far larger, are
 * summed in 2^-8 nm as before, added to E >> 27 and saturated.
 */
#include "basis_q.h"
#include "internal.h"

enum { DX = ABBE_TERM_DX, DY = ABBE_TERM_DY, DZ = ABBE_TERM_DZ, EX = ABBE_TERM_EX, EY = ABBE_TERM_EY, EZ = ABBE_TERM_EZ };

#define E_BITS 35                       /* E in 2^-35 nm */
#define LIN_TO_E ((int32_t)1 << (E_BITS - ABBE_TERM_LIN_Q_BITS)) /* 2^29 */

static int64_t mac(int64_t acc, int32_t a, int32_t b)
{
    return acc + (int64_t)a * b;
}

#if !defined(ABBE_NO_REVERSAL)
/* s (B + R(p)) for an axis with a reversal block (format 1.1), 2^-8 nm x
 * Q30: its backlash reversal B plus the block sum_k r_k T_k(u) at pos_nm
 * (clamped: the trend's u), times the direction state s. T_k come from the
 * trend's recurrence (the same roundings, so the same error bound per row);
 * the int64 sum starts at B x 2^30 and the rounding constant, and
 * |B| + sum |r_k| <= 2^31 (the loader's cap) keeps it below 2^62, so the
 * shift by 30 rounds it once to 2^-8 nm and |(B + R) s| < 2^62. Out of line:
 * only tables with the blocks run it. */
ABBE_NOINLINE static int64_t axis_reversal_times(const abbe_axis_model_t *ax, int32_t pos_nm, int32_t s)
{
    uint32_t flags = 0; /* out of travel: the evaluation has flagged it already */
    const uint8_t *row = ax->coef_q + 4u * ((unsigned)ax->n_basis * ax->n_terms);
    const int32_t u = abbe_arg_cheb_q30(ax, abbe_arg_offset(ax, pos_nm, &flags));
    int32_t t_prev = ABBE_Q30_ONE, t = u;
    int64_t acc = (int64_t)ax->backlash_reversal_q8 * ABBE_Q30_ONE + ((int64_t)1 << 29);
    acc = abbe_smlal(acc, abbe_ld_i32_aligned(row), ABBE_Q30_ONE); /* T_0 = 1 */
    /*@ loop unroll ABBE_MAX_REVERSAL_ROWS; */ /* the proofs: each row with its own state (docs/proofs.md) */
    for (unsigned k = 1; k < ax->reversal_rows; k++) {
        acc += (int64_t)abbe_ld_i32_aligned(row + 4u * k) * t;
        int32_t t_next = cheb_next_q30(u, t, t_prev); /* the trend's recurrence (basis_q.h) */
        t_prev = t;
        t = t_next;
    }
    return (acc >> 30) * s;
}
#endif

/* Component j of the error in nm, from its sum E (2^-35 nm, rounding
 * constant included) and the extra terms (backlash, thermal) on axis j's own
 * positioning error: -d_x(x) in dX, -d_y(y) in dY, +d_z(z) in dZ. The extras
 * can be far larger than E, so they are summed in W = 2^-8 nm (E >> 27 keeps
 * E's rounding constant, 2^7 W) and the result saturates (flagged). Inlined
 * once, in a loop over the components (only tables with the features run it). */
static ABBE_ALWAYS_INLINE int32_t finish_with_extras(const abbe_model_t *m, unsigned j, int64_t e, int32_t pos_nm,
                                                int32_t dir_q30, int32_t temp_mdegc, uint32_t *flags)
{
    const abbe_axis_model_t *ax = &m->axis[j];
    int64_t w = 0;
    if (m->features & ABBE_FEATURE_BACKLASH) {
        int32_t s = dir_q30 > ABBE_Q30_ONE ? ABBE_Q30_ONE : (dir_q30 < -ABBE_Q30_ONE ? -ABBE_Q30_ONE : dir_q30);
        int64_t bs = (int64_t)ax->backlash_reversal_q8 * s; /* s * B */
#if !defined(ABBE_NO_REVERSAL)
        if (ax->reversal_rows != 0u) {
            bs = axis_reversal_times(ax, pos_nm, s); /* s * (B + R(p)) */
        }
#endif
        w = abbe_shr_round(bs, 31u); /* s * B / 2 */
    }
    if (m->features & ABBE_FEATURE_THERMAL) {
        /* dT in mK, clamped to +/-2^30 (a million kelvin) so alpha * dT < 2^61. */
        int64_t dt = abbe_clamp_i64((int64_t)temp_mdegc - ax->thermal_tref_mdegc, -((int64_t)1 << 30),
                                    (int64_t)1 << 30);
        int64_t strain_a = abbe_shr_round((int64_t)ax->thermal_expansion_q50 * dt, 14u);
        if (strain_a > ABBE_Q30_ONE || strain_a < -ABBE_Q30_ONE) {
            *flags |= ABBE_FLAG_SATURATED;
            strain_a = abbe_clamp_i64(strain_a, -ABBE_Q30_ONE, ABBE_Q30_ONE);
        }
        /* lever [nm] * strain [2^-36] -> W, |lever| < 2^33: below 2^63 */
        w += abbe_shr_round(((int64_t)pos_nm - m->reference_nm[j]) * strain_a, 28u);
        w += abbe_shr_round((int64_t)ax->thermal_offset_q16 * dt, 8u);
    }
    return abbe_sat_i32(((e >> 27) + (j == 2u ? w : -w)) >> 8, flags);
}

/* Eq. 3 from the 18 term values (and the extras), into error_nm. A function
 * of its own, called after the kernels rather than around them, so the
 * stack holds one of them at a time. */
ABBE_NOINLINE static uint32_t assemble_q(const abbe_model_t *m, const int32_t pos_nm[ABBE_AXES],
                                         const int32_t dir_q30[ABBE_AXES], const int32_t temp_mdegc[ABBE_AXES],
                                         const int32_t values[ABBE_AXES * ABBE_TERMS], int32_t error_nm[ABBE_AXES],
                                         uint32_t flags)
{
    const int32_t *X = values, *Y = values + ABBE_TERMS, *Z = values + 2 * ABBE_TERMS;
    const int32_t px = pos_nm[0], py = pos_nm[1], pz = pos_nm[2];

    const int32_t rx = m->reference_nm[0], ry = m->reference_nm[1], rz = m->reference_nm[2];
    const int32_t tx = m->tool_offset_nm[0], ty = m->tool_offset_nm[1], tz = m->tool_offset_nm[2];
    /* e_xz + e_yz, e_xy + e_yy, e_xx + e_yx (each |A| <= 2^27: sums fit) */
    const int32_t ez = X[EZ] + Y[EZ], ey = X[EY] + Y[EY], ex = X[EX] + Y[EX];
    const int64_t half = (int64_t)1 << (E_BITS - 1);

    /* dX = -d_x(x) - d_x(y) + d_x(z) + (t_y - y) ez - (z + t_z) ey - t_y e_zz + t_z e_zy
     *      + y S_xy - z S_xz */
    int64_t e = mac(mac(mac(half, X[DX], -LIN_TO_E), Y[DX], -LIN_TO_E), Z[DX], LIN_TO_E);
    e = mac(mac(mac(e, ez, ty), ez, ry), -ez, py);
    e = mac(mac(mac(e, -ey, pz), ey, rz), -ey, tz);
    e = mac(mac(e, -Z[EZ], ty), Z[EY], tz);
    int64_t sq = mac(mac(m->square_const_q36[0], m->squareness_q36[0], py), -m->squareness_q36[1], pz);
    int64_t err_x = e + (sq >> 1);

    /* dY = -d_y(x) - d_y(y) + d_y(z) + x e_xz + t_x (e_zz - ez) + (z + t_z) ex - t_z e_zx - z S_yz */
    e = mac(mac(mac(half, X[DY], -LIN_TO_E), Y[DY], -LIN_TO_E), Z[DY], LIN_TO_E);
    e = mac(mac(e, X[EZ], px), -X[EZ], rx);
    e = mac(e, Z[EZ] - ez, tx);
    e = mac(mac(e, ex, pz), -ex, rz);
    e = mac(e, ex - Z[EX], tz);
    sq = mac(m->square_const_q36[1], -m->squareness_q36[2], pz);
    int64_t err_y = e + (sq >> 1);

    /* dZ = -d_z(x) - d_z(y) + d_z(z) - x e_xy + t_x (ey - e_zy) + y ex + t_y (e_zx - ex) */
    e = mac(mac(mac(half, X[DZ], -LIN_TO_E), Y[DZ], -LIN_TO_E), Z[DZ], LIN_TO_E);
    e = mac(mac(e, -X[EY], px), X[EY], rx);
    e = mac(e, ey - Z[EY], tx);
    e = mac(mac(e, ex, py), -ex, ry);
    e = mac(e, Z[EX] - ex, ty);
    int64_t err_z = e;

    if (m->features & (ABBE_FEATURE_BACKLASH | ABBE_FEATURE_THERMAL)) {
        const int64_t e3[ABBE_AXES] = {err_x, err_y, err_z};
        for (unsigned j = 0; j < ABBE_AXES; j++) {
            error_nm[j] = finish_with_extras(m, j, e3[j], pos_nm[j], dir_q30[j], temp_mdegc[j], &flags);
        }
    } else {
        error_nm[0] = (int32_t)(err_x >> E_BITS);
        error_nm[1] = (int32_t)(err_y >> E_BITS);
        error_nm[2] = (int32_t)(err_z >> E_BITS);
    }
    return flags;
}

uint32_t abbe_eval_q_core(const abbe_model_t *m, const int32_t pos_nm[ABBE_AXES],
                          const int32_t dir_q30[ABBE_AXES], const int32_t temp_mdegc[ABBE_AXES],
                          int32_t values[ABBE_AXES * ABBE_TERMS], int32_t error_nm[ABBE_AXES])
{
    uint32_t flags = 0;
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        const abbe_axis_model_t *ax = &m->axis[j];
        abbe_axis_terms_q(ax, abbe_arg_offset(ax, pos_nm[j], &flags), values + ABBE_TERMS * j);
    }
    return assemble_q(m, pos_nm, dir_q30, temp_mdegc, values, error_nm, flags);
}

abbe_status_t abbe_error_eval_q(const abbe_model_t *m, const abbe_input_q_t *in, abbe_error_q_t *out)
{
    if (m == NULL || in == NULL || out == NULL) {
        return ABBE_E_ARG;
    }
    int32_t values[ABBE_AXES * ABBE_TERMS];
    out->flags = abbe_eval_q_core(m, in->pos_nm, in->dir_state_q30, in->temp_mdegc, values, out->error_nm);
    return ABBE_OK;
}

abbe_status_t abbe_error_eval_batch_q(const abbe_model_t *m, size_t n, const abbe_input_q_t *in,
                                      abbe_error_q_t *out)
{
    if (m == NULL || (n > 0u && (in == NULL || out == NULL))) {
        return ABBE_E_ARG;
    }
    int32_t values[ABBE_AXES * ABBE_TERMS];
    for (size_t i = 0; i < n; i++) {
        out[i].flags = abbe_eval_q_core(m, in[i].pos_nm, in[i].dir_state_q30, in[i].temp_mdegc, values,
                                        out[i].error_nm);
    }
    return ABBE_OK;
}

abbe_status_t abbe_term_eval_q(const abbe_model_t *m, unsigned axis, unsigned term, abbe_nm_t pos_nm,
                               int32_t *value_pm_or_prad)
{
    if (m == NULL || value_pm_or_prad == NULL || axis >= ABBE_AXES || term >= ABBE_TERMS) {
        return ABBE_E_ARG;
    }
    uint32_t flags = 0;
    const abbe_axis_model_t *ax = &m->axis[axis];
    int32_t v[ABBE_TERMS];
    abbe_axis_terms_q(ax, abbe_arg_offset(ax, pos_nm, &flags), v);
    int64_t pico;
    if (term < 3u) {
        pico = abbe_shr_round((int64_t)v[term] * 125, 3u); /* 2^-6 nm -> pm: * 1000 / 64 */
    } else {
        pico = abbe_shr_round((int64_t)v[term] * 244140625, 23u); /* 2^-35 rad -> prad: * 10^12 / 2^35 */
    }
    *value_pm_or_prad = abbe_sat_i32(pico, &flags);
    return ABBE_OK;
}

abbe_status_t abbe_reversal_eval_q(const abbe_model_t *m, unsigned axis, abbe_nm_t pos_nm, int32_t *value_pm)
{
    if (m == NULL || value_pm == NULL || axis >= ABBE_AXES) {
        return ABBE_E_ARG;
    }
    uint32_t flags = 0;
    const abbe_axis_model_t *ax = &m->axis[axis];
    int64_t r = ax->backlash_reversal_q8; /* 2^-8 nm */
#if !defined(ABBE_NO_REVERSAL)
    if (ax->reversal_rows != 0u) {
        r = axis_reversal_times(ax, pos_nm, 1);
    }
#else
    (void)pos_nm;
#endif
    *value_pm = abbe_sat_i32(abbe_shr_round(r * 125, 5u), &flags); /* 2^-8 nm -> pm: * 1000 / 256 */
    return ABBE_OK;
}
