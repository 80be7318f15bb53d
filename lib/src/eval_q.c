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
 * (backlash, thermal), which can be far larger, are summed in 2^-8 nm as
 * before, added to E >> 27 and saturated.
 */
#include "internal.h"

enum { DX = ABBE_TERM_DX, DY = ABBE_TERM_DY, DZ = ABBE_TERM_DZ, EX = ABBE_TERM_EX, EY = ABBE_TERM_EY, EZ = ABBE_TERM_EZ };

#define E_BITS 35                       /* E in 2^-35 nm */
#define LIN_TO_E ((int32_t)1 << (E_BITS - ABBE_TERM_LIN_Q_BITS)) /* 2^29 */

static int64_t mac(int64_t acc, int32_t a, int32_t b)
{
    return acc + (int64_t)a * b;
}

/* lever [nm] * angle [2^-36 rad] -> W [2^-8 nm], rounded */
static int64_t lever_w(int64_t lever_nm, int64_t angle_a)
{
    return abbe_shr_round(lever_nm * angle_a, 28u);
}

/* Extra terms on the axis' own positioning error, in W = 2^-8 nm. */
static int64_t extras_w(const abbe_model_t *m, unsigned j, int64_t lever_nm, int32_t dir_q30,
                        int32_t temp_mdegc, uint32_t *flags)
{
    const abbe_axis_model_t *ax = &m->axis[j];
    int64_t w = 0;
    if (m->features & ABBE_FEATURE_BACKLASH) {
        int64_t s = abbe_clamp_i64(dir_q30, -ABBE_Q30_ONE, ABBE_Q30_ONE);
        w += abbe_shr_round((int64_t)ax->backlash_reversal_q8 * s, 31u); /* s * B / 2 */
    }
    if (m->features & ABBE_FEATURE_THERMAL) {
        /* dT in mK, clamped to +/-2^30 (a million kelvin) so alpha * dT < 2^61. */
        int64_t dt = abbe_clamp_i64((int64_t)temp_mdegc - ax->thermal_tref_mdegc,
                                    -((int64_t)1 << 30), (int64_t)1 << 30);
        int64_t strain_a = abbe_shr_round((int64_t)ax->thermal_expansion_q50 * dt, 14u);
        if (strain_a > ABBE_Q30_ONE || strain_a < -ABBE_Q30_ONE) {
            *flags |= ABBE_FLAG_SATURATED;
            strain_a = abbe_clamp_i64(strain_a, -ABBE_Q30_ONE, ABBE_Q30_ONE);
        }
        w += lever_w(lever_nm, strain_a);
        w += abbe_shr_round((int64_t)ax->thermal_offset_q16 * dt, 8u);
    }
    return w;
}

uint32_t abbe_eval_q_core(const abbe_model_t *m, const int32_t pos_nm[ABBE_AXES],
                          const int32_t dir_q30[ABBE_AXES], const int32_t temp_mdegc[ABBE_AXES],
                          int32_t error_nm[ABBE_AXES])
{
    uint32_t flags = 0;
    int32_t X[ABBE_TERMS], Y[ABBE_TERMS], Z[ABBE_TERMS];
    const int32_t px = pos_nm[0], py = pos_nm[1], pz = pos_nm[2];
    abbe_axis_terms_q(&m->axis[0], abbe_arg_offset(&m->axis[0], px, &flags), X);
    abbe_axis_terms_q(&m->axis[1], abbe_arg_offset(&m->axis[1], py, &flags), Y);
    abbe_axis_terms_q(&m->axis[2], abbe_arg_offset(&m->axis[2], pz, &flags), Z);

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
        /* own positioning terms: -d_x(x) in dX, -d_y(y) in dY, +d_z(z) in dZ;
         * E >> 27 is in 2^-8 nm and keeps the rounding constant (2^7) */
        int64_t w[ABBE_AXES];
        for (unsigned j = 0; j < ABBE_AXES; j++) {
            int64_t lever = (int64_t)pos_nm[j] - m->reference_nm[j];
            w[j] = extras_w(m, j, lever, dir_q30[j], temp_mdegc[j], &flags);
        }
        error_nm[0] = abbe_sat_i32(((err_x >> 27) - w[0]) >> 8, &flags);
        error_nm[1] = abbe_sat_i32(((err_y >> 27) - w[1]) >> 8, &flags);
        error_nm[2] = abbe_sat_i32(((err_z >> 27) + w[2]) >> 8, &flags);
    } else {
        error_nm[0] = (int32_t)(err_x >> E_BITS);
        error_nm[1] = (int32_t)(err_y >> E_BITS);
        error_nm[2] = (int32_t)(err_z >> E_BITS);
    }
    return flags;
}

abbe_status_t abbe_error_eval_q(const abbe_model_t *m, const abbe_input_q_t *in, abbe_error_q_t *out)
{
    if (m == NULL || in == NULL || out == NULL) {
        return ABBE_E_ARG;
    }
    out->flags = abbe_eval_q_core(m, in->pos_nm, in->dir_state_q30, in->temp_mdegc, out->error_nm);
    return ABBE_OK;
}

abbe_status_t abbe_error_eval_batch_q(const abbe_model_t *m, size_t n, const abbe_input_q_t *in,
                                      abbe_error_q_t *out)
{
    if (m == NULL || (n > 0u && (in == NULL || out == NULL))) {
        return ABBE_E_ARG;
    }
    for (size_t i = 0; i < n; i++) {
        out[i].flags = abbe_eval_q_core(m, in[i].pos_nm, in[i].dir_state_q30, in[i].temp_mdegc,
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
