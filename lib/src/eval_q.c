/* abbe: spatial error, fixed point (Eq. 3 + Abbe terms + extras).
 *
 * Units: linear values W = 2^-8 nm (int64), angles A = 2^-36 rad, lever arms nm.
 * A lever (< 2^32 nm) times a sum of at most three angles (< 3 * 2^28 A, by the
 * table's range caps) stays below 2^62 and converts to W with one rounding.
 * The final W sums round to nm and saturate to int32 (flagged).
 */
#include "internal.h"

enum { DX = ABBE_TERM_DX, DY = ABBE_TERM_DY, DZ = ABBE_TERM_DZ, EX = ABBE_TERM_EX, EY = ABBE_TERM_EY, EZ = ABBE_TERM_EZ };

/* lever [nm] * angle [2^-36 rad] -> W [2^-8 nm] */
static int64_t lever_w(int64_t lever_nm, int64_t angle_a)
{
    return abbe_shr_round(lever_nm * angle_a, 28u);
}

/* Extra terms on the axis' own positioning error, in W. */
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

abbe_status_t abbe_error_eval_q(const abbe_model_t *m, const abbe_input_q_t *in, abbe_error_q_t *out)
{
    if (m == NULL || in == NULL || out == NULL) {
        return ABBE_E_ARG;
    }
    uint32_t flags = 0;
    int64_t v[ABBE_AXES][ABBE_TERMS]; /* v[j][0..2] = d_x,y,z(j) in W; v[j][3..5] = eps_jx,y,z in A */
    int64_t lev[ABBE_AXES];
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        abbe_axis_terms_q(&m->axis[j], in->pos_nm[j], v[j], &flags);
        lev[j] = (int64_t)in->pos_nm[j] - m->reference_nm[j];
        v[j][j] += extras_w(m, j, lev[j], in->dir_state_q30[j], in->temp_mdegc[j], &flags);
    }
    const int64_t x = lev[0], y = lev[1], z = lev[2];
    const int64_t sxy = m->squareness_q36[0], sxz = m->squareness_q36[1], syz = m->squareness_q36[2];
    const int64_t *X = v[0], *Y = v[1], *Z = v[2];

    int64_t err_x = -X[DX] - Y[DX] + Z[DX] + lever_w(y, sxy - X[EZ] - Y[EZ]) +
                 lever_w(z, -sxz - X[EY] - Y[EY]);
    int64_t err_y = -X[DY] - Y[DY] + Z[DY] + lever_w(x, X[EZ]) +
                 lever_w(z, X[EX] + Y[EX] - syz);
    int64_t err_z = -X[DZ] - Y[DZ] + Z[DZ] + lever_w(x, -X[EY]) +
                 lever_w(y, X[EX] + Y[EX]);

    if (m->features & ABBE_FEATURE_TOOL_OFFSET) {
        const int64_t tx = m->tool_offset_nm[0], ty = m->tool_offset_nm[1], tz = m->tool_offset_nm[2];
        err_x += lever_w(ty, X[EZ] + Y[EZ] - Z[EZ]) + lever_w(tz, Z[EY] - X[EY] - Y[EY]);
        err_y += lever_w(tx, Z[EZ] - X[EZ] - Y[EZ]) + lever_w(tz, X[EX] + Y[EX] - Z[EX]);
        err_z += lever_w(tx, X[EY] + Y[EY] - Z[EY]) + lever_w(ty, Z[EX] - X[EX] - Y[EX]);
    }

    out->error_nm[0] = abbe_sat_i32(abbe_shr_round(err_x, 8u), &flags);
    out->error_nm[1] = abbe_sat_i32(abbe_shr_round(err_y, 8u), &flags);
    out->error_nm[2] = abbe_sat_i32(abbe_shr_round(err_z, 8u), &flags);
    out->flags = flags;
    return ABBE_OK;
}

abbe_status_t abbe_term_eval_q(const abbe_model_t *m, unsigned axis, unsigned term, abbe_nm_t pos_nm,
                               int32_t *value_pm_or_prad)
{
    if (m == NULL || value_pm_or_prad == NULL || axis >= ABBE_AXES || term >= ABBE_TERMS) {
        return ABBE_E_ARG;
    }
    uint32_t flags = 0;
    int64_t v[ABBE_TERMS];
    abbe_axis_terms_q(&m->axis[axis], pos_nm, v, &flags);
    int64_t pico;
    if (term < 3u) {
        pico = abbe_shr_round(v[term] * 125, 5u); /* 2^-8 nm -> pm: * 1000 / 256 */
    } else {
        pico = abbe_shr_round(v[term] * 244140625, 24u); /* 2^-36 rad -> prad: * 10^12 / 2^36 */
    }
    *value_pm_or_prad = abbe_sat_i32(pico, &flags);
    return ABBE_OK;
}
