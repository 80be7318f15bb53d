/* abbe grblHAL plugin core, the model's evaluation outside the compensator:
 * the curvature scan that sets the segment length at table load
 * (abbe_gh_curvature) and the inverse transform of every position report
 * (abbe_gh_inverse) (include/abbe_grblhal_core.h). C99, no heap, no I/O. */
#include <string.h>

#include "abbe_grblhal_core_private.h"

/* Samples per axis line of the curvature scan (abbe_gh_curvature). */
#ifndef ABBE_GH_CURV_SAMPLES
#define ABBE_GH_CURV_SAMPLES 256
#endif

/* Spatial error E at pos (mm), um, direction state 0, thermal term off
 * (temperature = the table's reference). The variant the build uses. */
static void eval_um(const abbe_model_t *model, const float tref_c[ABBE_AXES], const float pos[ABBE_AXES],
                    float err_um[ABBE_AXES])
{
#if ABBE_GH_FIXED_POINT
    abbe_input_q_t in;
    abbe_error_q_t out;
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        in.pos_nm[j] = mm_to_nm(pos[j]);
        in.dir_state_q30[j] = 0;
        in.temp_mdegc[j] = (int32_t)(tref_c[j] * 1000.0f + (tref_c[j] >= 0.0f ? 0.5f : -0.5f));
    }
    (void)abbe_error_eval_q(model, &in, &out);
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        err_um[j] = (float)out.error_nm[j] * 1.0e-3f;
    }
#else
    abbe_input_f32_t in;
    abbe_error_f32_t out;
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        in.pos_mm[j] = pos[j];
        in.dir_state[j] = 0.0f;
        in.temp_c[j] = tref_c[j];
    }
    if (abbe_error_eval_f32(model, &in, &out) != ABBE_OK) {
        memset(out.error_um, 0, sizeof out.error_um);
    }
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        err_um[j] = out.error_um[j];
    }
#endif
}

abbe_status_t abbe_gh_curvature(const abbe_model_t *model, float *kappa_um_per_mm2)
{
    if (model == NULL || kappa_um_per_mm2 == NULL) {
        return ABBE_E_ARG;
    }
    float lo[ABBE_AXES], hi[ABBE_AXES], tref[ABBE_AXES];
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        abbe_axis_info_t info;
        abbe_status_t st = abbe_model_axis_info(model, j, &info);
        if (st != ABBE_OK) {
            return st;
        }
        lo[j] = (float)info.travel_min_nm * MM_PER_NM;
        hi[j] = (float)info.travel_max_nm * MM_PER_NM;
        tref[j] = (float)info.thermal_tref_mdegc * 1.0e-3f;
    }
    float shortest = hi[0] - lo[0];
    for (unsigned j = 1; j < ABBE_AXES; j++) {
        shortest = hi[j] - lo[j] < shortest ? hi[j] - lo[j] : shortest;
    }
    float kappa = 0.0f;
    for (unsigned a = 0; a < ABBE_AXES; a++) {
        unsigned b = (a + 1u) % ABBE_AXES, c = (a + 2u) % ABBE_AXES;
        float span = hi[a] - lo[a];
        /* differences over h = min(span / ABBE_GH_CURV_SAMPLES, 0.5 mm, a
         * quarter of the shortest travel) */
        float step = span / (float)ABBE_GH_CURV_SAMPLES;
        float h = step < 0.5f ? step : 0.5f;
        h = h < 0.25f * shortest ? h : 0.25f * shortest;
        if (!(h > 0.0f)) {
            continue;
        }
        /* Every point of the stencil (p, p +- h e_i, p + h e_i + h e_j) inside
         * the travel: each coordinate of p in [lo + h, hi - h]. Outside the
         * travel the library holds each term at its end value: a stencil
         * reaching there measures the kink at the end (the slope over h), not
         * a curvature, and made the segments 3x shorter than the bound needs
         * (vmc500: 0.495 against 0.053 um/mm^2). */
        uint32_t n = (uint32_t)ABBE_GH_CURV_SAMPLES - 1u;
        float pitch = (span - 2.0f * h) / (float)(n - 1u);
        for (unsigned corner = 0; corner < 4u; corner++) {
            float p[ABBE_AXES];
            p[b] = (corner & 1u) ? hi[b] - h : lo[b] + h;
            p[c] = (corner & 2u) ? hi[c] - h : lo[c] + h;
            for (uint32_t k = 0; k < n; k++) {
                p[a] = lo[a] + h + (float)k * pitch;
                /* E at p, p +- h e_i, p + h e_i + h e_j: the Hessian of each
                 * error component by central (diagonal) and forward (mixed)
                 * differences. */
                float e0[ABBE_AXES], ep[ABBE_AXES][ABBE_AXES], em[ABBE_AXES][ABBE_AXES];
                float epp[ABBE_AXES][ABBE_AXES]; /* [pair][component]: pairs (0,1) (0,2) (1,2) */
                float q[ABBE_AXES];
                eval_um(model, tref, p, e0);
                for (unsigned i = 0; i < ABBE_AXES; i++) {
                    memcpy(q, p, sizeof q);
                    q[i] = p[i] + h;
                    eval_um(model, tref, q, ep[i]);
                    q[i] = p[i] - h;
                    eval_um(model, tref, q, em[i]);
                }
                static const unsigned pair[3][2] = {{0u, 1u}, {0u, 2u}, {1u, 2u}};
                for (unsigned pi = 0; pi < 3u; pi++) {
                    memcpy(q, p, sizeof q);
                    q[pair[pi][0]] += h;
                    q[pair[pi][1]] += h;
                    eval_um(model, tref, q, epp[pi]);
                }
                float inv_h2 = 1.0f / (h * h);
                for (unsigned comp = 0; comp < ABBE_AXES; comp++) {
                    float hess[ABBE_AXES][ABBE_AXES];
                    for (unsigned i = 0; i < ABBE_AXES; i++) {
                        hess[i][i] = (ep[i][comp] - 2.0f * e0[comp] + em[i][comp]) * inv_h2;
                    }
                    for (unsigned pi = 0; pi < 3u; pi++) {
                        unsigned i = pair[pi][0], j = pair[pi][1];
                        float m = (epp[pi][comp] - ep[i][comp] - ep[j][comp] + e0[comp]) * inv_h2;
                        hess[i][j] = m;
                        hess[j][i] = m;
                    }
                    for (unsigned i = 0; i < ABBE_AXES; i++) {
                        float row = absf(hess[i][0]) + absf(hess[i][1]) + absf(hess[i][2]);
                        if (row > kappa) {
                            kappa = row;
                        }
                    }
                }
            }
        }
    }
    *kappa_um_per_mm2 = kappa;
    return ABBE_OK;
}

int abbe_gh_inverse(const abbe_gh_t *gh, const float motor[ABBE_AXES], float cart[ABBE_AXES])
{
    const abbe_model_t *model = abbe_comp_model(&gh->comp);
    float base[ABBE_AXES];
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        base[j] = (float)gh->last_corr_nm[j] * MM_PER_NM;
        cart[j] = motor[j] - base[j];
    }
    if (model == NULL || !gh->have_last || !any_correction(gh)) {
        return 0;
    }
    const float *tref = gh->slot[gh->running != NO_SLOT ? gh->running : 0u].tref_c;
    float e_last[ABBE_AXES];
    eval_um(model, tref, gh->last_cart, e_last);
    int it;
    for (it = 1; it <= 4; it++) {
        float e[ABBE_AXES], moved = 0.0f;
        eval_um(model, tref, cart, e);
        for (unsigned j = 0; j < ABBE_AXES; j++) {
            /* c(q) = c_last + (-(E(q) - E(last))) */
            float c = base[j] - (e[j] - e_last[j]) / UM_PER_MM;
            float q = motor[j] - c;
            moved = absf(q - cart[j]) > moved ? absf(q - cart[j]) : moved;
            cart[j] = q;
        }
        if (moved < 1.0e-6f) {
            break;
        }
    }
    return it > 4 ? 4 : it;
}
