/* abbe grblHAL plugin core: segmentation, forward and inverse transform,
 * enable / fade / fault and table upload over the abbe library
 * (include/abbe_grblhal_core.h). C99, no heap, no I/O. */
#include <string.h>

#include "abbe_grblhal_core.h"

#define NM_PER_MM 1.0e6f
#define MM_PER_NM 1.0e-6f
#define UM_PER_MM 1.0e3f
#define NO_SLOT 0xFFu

/* Samples per axis line of the curvature scan (abbe_gh_curvature). */
#ifndef ABBE_GH_CURV_SAMPLES
#define ABBE_GH_CURV_SAMPLES 256
#endif

/* mm -> nm, rounded, clamped to int32 (the library clamps to the travel anyway). */
static int32_t mm_to_nm(float mm)
{
    float nm = mm * NM_PER_MM;
    if (!(nm < 2147483520.0f)) { /* also NaN: the compensator flags it as input */
        return nm > 0.0f ? INT32_MAX : 0;
    }
    if (nm <= -2147483520.0f) {
        return INT32_MIN + 1;
    }
    return (int32_t)(nm >= 0.0f ? nm + 0.5f : nm - 0.5f);
}

static float absf(float x)
{
    return x < 0.0f ? -x : x;
}

/* Square root by Newton's method (no libm in the plugin core; only used at
 * table load and parameter changes). x >= 0. */
static float sqrt_pos(float x)
{
    if (!(x > 0.0f)) {
        return 0.0f;
    }
    float r = x > 1.0f ? x : 1.0f;
    for (int i = 0; i < 40; i++) {
        float next = 0.5f * (r + x / r);
        if (absf(next - r) <= 1.0e-7f * next) {
            return next;
        }
        r = next;
    }
    return r;
}

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

void abbe_gh_default_params(abbe_gh_params_t *params)
{
    params->max_dev_um = 1.0f;
    params->limit_um = 200.0f;
    params->rate_um_per_seg = 10.0f;
    params->fade_segments = 32u;
}

static int params_valid(const abbe_gh_params_t *p)
{
    return p->max_dev_um >= 0.01f && p->max_dev_um <= 100.0f && p->limit_um >= 1.0f &&
           p->limit_um <= 2000.0f && p->rate_um_per_seg >= 0.1f && p->rate_um_per_seg <= 2000.0f &&
           p->fade_segments >= 1u;
}

static void comp_config(const abbe_gh_params_t *p, abbe_comp_config_t *cfg)
{
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        cfg->limit_nm[j] = mm_to_nm(p->limit_um / UM_PER_MM);
        cfg->warn_nm[j] = cfg->limit_nm[j] / 2 > 0 ? cfg->limit_nm[j] / 2 : 1;
        cfg->rate_nm_per_cycle[j] = mm_to_nm(p->rate_um_per_seg / UM_PER_MM);
        cfg->axis_sign[j] = 1;
    }
    cfg->fade_cycles = p->fade_segments;
    cfg->stale_cycles = 65535u; /* a cycle is a segment: the plugin steps only on motion */
}

float abbe_gh_segment_length(float dev_um, float kappa_um_per_mm2)
{
    if (!(kappa_um_per_mm2 > 0.0f) || !(dev_um > 0.0f)) {
        return ABBE_GH_SEG_MAX_MM;
    }
    float len = sqrt_pos(8.0f * dev_um / kappa_um_per_mm2);
    if (len < ABBE_GH_SEG_MIN_MM) {
        return ABBE_GH_SEG_MIN_MM;
    }
    return len > ABBE_GH_SEG_MAX_MM ? ABBE_GH_SEG_MAX_MM : len;
}

float abbe_gh_deviation_um(float len_mm, float kappa_um_per_mm2)
{
    return len_mm * len_mm * 0.125f * kappa_um_per_mm2;
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

/* Validate blob into slot s and derive what segmentation needs. */
static abbe_status_t slot_prepare(abbe_gh_slot_t *s)
{
    float kappa = 0.0f;
    abbe_status_t st = abbe_gh_curvature(&s->model, &kappa);
    if (st != ABBE_OK) {
        return st;
    }
    s->kappa_um_per_mm2 = kappa;
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        abbe_axis_info_t info;
        (void)abbe_model_axis_info(&s->model, j, &info);
        s->takeup_mm[j] = (float)info.backlash_takeup_nm * MM_PER_NM;
        s->tref_c[j] = (float)info.thermal_tref_mdegc * 1.0e-3f;
        s->travel_lo_mm[j] = (float)info.travel_min_nm * MM_PER_NM;
        s->travel_hi_mm[j] = (float)info.travel_max_nm * MM_PER_NM;
    }
    s->loaded = 1u;
    return ABBE_OK;
}

/* The running table's thermal block starts from nothing: weights 0, it fades
 * in after its first good sample. The period given to init is unused: the
 * plugin advances it by elapsed ms (abbe_thermal_apply_ms_*). */
static void thermal_start(abbe_gh_t *gh)
{
    const abbe_thermal_model_t *th = gh->running != NO_SLOT ? &gh->slot[gh->running].thermal : NULL;
    gh->thermal_on = 0u;
    gh->thermal_applied = 0u;
    gh->thermal_sampled = 0u;
    if (th == NULL || abbe_thermal_n_channels(th) == 0u) {
        return;
    }
#if ABBE_GH_FIXED_POINT
    gh->thermal_on = abbe_thermal_init_q(&gh->thermal, th, 1000u) == ABBE_OK;
#else
    gh->thermal_on = abbe_thermal_init_f32(&gh->thermal, th, 0.001f) == ABBE_OK;
#endif
}

void abbe_gh_clock(abbe_gh_t *gh, uint32_t now_ms)
{
    gh->now_ms = now_ms;
}

const abbe_thermal_state_t *abbe_gh_thermal(const abbe_gh_t *gh)
{
    return gh != NULL && gh->thermal_on ? &gh->thermal : NULL;
}

abbe_status_t abbe_gh_thermal_sample(abbe_gh_t *gh, const float x[], uint32_t valid_mask, const char **why)
{
    static const char *const none = "";
    *why = none;
    if (gh == NULL || x == NULL || !gh->thermal_on) {
        *why = "the running table has no thermal block";
        return ABBE_E_ARG;
    }
    uint32_t dt_ms = gh->thermal_sampled ? gh->now_ms - gh->thermal_sample_ms : 0u;
    if (gh->thermal_sampled && dt_ms == 0u) {
        *why = "a second sample in the same millisecond";
        return ABBE_E_ARG;
    }
    abbe_status_t st;
#if ABBE_GH_FIXED_POINT
    int32_t xm[ABBE_THERMAL_MAX_INPUTS];
    unsigned n = abbe_thermal_n_inputs(gh->thermal.model);
    for (unsigned k = 0; k < n; k++) {
        /* _q takes m degC, and rpm as they are (rpm = milli-krpm) */
        float v = gh->thermal.model->kind[k] == ABBE_THERMAL_SPEED ? x[k] : x[k] * 1000.0f;
        /* out of the int32 range (or NaN): no reading the block accepts; its range check flags it */
        if (!(v > -2.0e9f && v < 2.0e9f)) {
            xm[k] = INT32_MAX;
        } else {
            xm[k] = (int32_t)(v + (v >= 0.0f ? 0.5f : -0.5f));
        }
    }
    st = abbe_thermal_update_q(&gh->thermal, xm, valid_mask, dt_ms);
#else
    st = abbe_thermal_update_f32(&gh->thermal, x, valid_mask, (float)dt_ms * 0.001f);
#endif
    if (st != ABBE_OK) {
        *why = abbe_strerror(st);
        return st;
    }
    gh->thermal_sample_ms = gh->now_ms;
    gh->thermal_sampled = 1u;
    return ABBE_OK;
}

/* Segment length for the current parameters: the shorter of the running and
 * the queued table's while a swap is pending. */
static void update_seg_len(abbe_gh_t *gh)
{
    float len = ABBE_GH_SEG_MAX_MM;
    if (gh->running != NO_SLOT) {
        len = abbe_gh_segment_length(gh->params.max_dev_um, gh->slot[gh->running].kappa_um_per_mm2);
    }
    if (gh->pending != NO_SLOT) {
        float l2 = abbe_gh_segment_length(gh->params.max_dev_um, gh->slot[gh->pending].kappa_um_per_mm2);
        len = l2 < len ? l2 : len;
    }
    gh->seg_len_mm = len;
}

abbe_status_t abbe_gh_init(abbe_gh_t *gh, const abbe_gh_params_t *params, const void *blob, size_t size)
{
    if (gh == NULL || params == NULL || !params_valid(params)) {
        return ABBE_E_ARG;
    }
    if (blob != NULL && blob == (const void *)gh->slot[0].blob) {
        /* a stored table read into slot 0's RAM: clear everything but the blobs */
        memset(&gh->comp, 0, sizeof gh->comp);
        for (unsigned k = 0; k < 2u; k++) {
            memset(&gh->slot[k], 0, offsetof(abbe_gh_slot_t, blob));
        }
        memset(&gh->params, 0, sizeof *gh - offsetof(abbe_gh_t, params));
    } else {
        memset(gh, 0, sizeof *gh);
    }
    gh->params = *params;
    gh->running = NO_SLOT;
    gh->pending = NO_SLOT;
    abbe_comp_config_t cfg;
    comp_config(params, &cfg);
    abbe_status_t st = ABBE_OK;
    if (blob != NULL) {
        st = abbe_thermal_load(&gh->slot[0].model, &gh->slot[0].thermal, blob, size);
        if (st == ABBE_OK) {
            st = slot_prepare(&gh->slot[0]);
        }
    }
    /* The table is the compensator's model from the start (nothing ran yet). */
    abbe_status_t st_comp = abbe_comp_init(&gh->comp, &cfg, blob != NULL && st == ABBE_OK ? &gh->slot[0].model : NULL);
    if (st == ABBE_OK) {
        st = st_comp;
    }
    if (st == ABBE_OK && blob != NULL) {
        gh->running = 0u;
        thermal_start(gh);
    } else if (st != ABBE_OK) {
        gh->slot[0].loaded = 0u;
        (void)abbe_comp_init(&gh->comp, &cfg, NULL);
    }
    update_seg_len(gh);
    return st;
}

uint8_t *abbe_gh_boot_buffer(abbe_gh_t *gh)
{
    return (uint8_t *)gh->slot[0].blob;
}

abbe_status_t abbe_gh_rehome(abbe_gh_t *gh)
{
    if (gh == NULL) {
        return ABBE_E_ARG;
    }
    if (gh->comp_state == ABBE_COMP_FAULT) {
        return ABBE_OK;
    }
    if (gh->pending != NO_SLOT) {
        gh->running = gh->pending;
        gh->pending = NO_SLOT;
    }
    abbe_comp_config_t cfg;
    comp_config(&gh->params, &cfg);
    /* A fresh compensator: output zero, gains zero, direction states zero. */
    abbe_status_t st = abbe_comp_init(&gh->comp, &cfg, gh->running != NO_SLOT ? &gh->slot[gh->running].model : NULL);
    if (st != ABBE_OK) {
        return st;
    }
    memset(gh->last_corr_nm, 0, sizeof gh->last_corr_nm);
    gh->flags = 0u;
    gh->comp_state = ABBE_COMP_OFF;
    update_seg_len(gh);
    return gh->enabled ? abbe_comp_enable(&gh->comp) : ABBE_OK;
}

abbe_status_t abbe_gh_set_params(abbe_gh_t *gh, const abbe_gh_params_t *params)
{
    if (gh == NULL || params == NULL || !params_valid(params)) {
        return ABBE_E_ARG;
    }
    abbe_comp_config_t cfg;
    comp_config(params, &cfg);
    abbe_status_t st = abbe_comp_set_config(&gh->comp, &cfg);
    if (st == ABBE_OK) {
        gh->params = *params;
        update_seg_len(gh);
    }
    return st;
}

abbe_status_t abbe_gh_set_enabled(abbe_gh_t *gh, int enable)
{
    if (gh == NULL) {
        return ABBE_E_ARG;
    }
    if (enable == 2) {
        gh->enabled = 0u;
        return abbe_comp_reset(&gh->comp);
    }
    gh->enabled = enable ? 1u : 0u;
    return enable ? abbe_comp_enable(&gh->comp) : abbe_comp_disable(&gh->comp);
}

static int any_correction(const abbe_gh_t *gh)
{
    return gh->last_corr_nm[0] != 0 || gh->last_corr_nm[1] != 0 || gh->last_corr_nm[2] != 0;
}

abbe_gh_state_t abbe_gh_state(const abbe_gh_t *gh)
{
    if (gh->comp_state == ABBE_COMP_FAULT) {
        return ABBE_GH_FAULT;
    }
    if (gh->flags & ABBE_FLAG_FADING) {
        return ABBE_GH_FADING;
    }
    if (gh->enabled && gh->running != NO_SLOT) {
        /* Enabled but no segment ran yet: the fade-in starts with the next one. */
        return gh->comp_state == ABBE_COMP_ON ? ABBE_GH_ON : ABBE_GH_FADING;
    }
    return any_correction(gh) ? ABBE_GH_FADING : ABBE_GH_OFF;
}

int abbe_gh_active(const abbe_gh_t *gh)
{
    if (gh->running == NO_SLOT && gh->pending == NO_SLOT) {
        return 0;
    }
    return gh->enabled || any_correction(gh) || (gh->flags & ABBE_FLAG_FADING) != 0u;
}

/* Insert t into the ascending list ends[0..*n) unless it lies within 1e-6
 * of an entry (the same break); the last place stays for the line's end (at
 * most 3 x 3 breaks come: a take-up end and two faces per axis). */
static void add_break(float ends[ABBE_GH_LINE_PIECES], uint32_t *n, float t)
{
    uint32_t k = 0u;
    while (k < *n && ends[k] < t) {
        k++;
    }
    if ((k < *n && ends[k] - t < 1.0e-6f) || (k > 0u && t - ends[k - 1u] < 1.0e-6f) ||
        *n >= ABBE_GH_LINE_PIECES - 1u) {
        return;
    }
    for (uint32_t m = *n; m > k; m--) {
        ends[m] = ends[m - 1u];
    }
    ends[k] = t;
    (*n)++;
}

uint32_t abbe_gh_line_begin(const abbe_gh_t *gh, abbe_gh_line_t *line, const float start[ABBE_AXES],
                            const float end[ABBE_AXES])
{
    float len2 = 0.0f;
    const abbe_gh_slot_t *s = gh->running != NO_SLOT ? &gh->slot[gh->running] : NULL;
    line->pieces = 0u;
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        line->start[j] = start[j];
        line->end[j] = end[j];
        float d = end[j] - start[j];
        len2 += d * d;
        /* NOLINTNEXTLINE(bugprone-narrowing-conversions): -1, 0 or 1 fit an int8_t */
        int8_t dir = d > 0.0f ? 1 : (d < 0.0f ? -1 : 0);
        if (s == NULL || dir == 0) {
            continue;
        }
        /* A reversal of an axis with a take-up: its direction state ramps
         * linearly over the take-up distance; a segment that ends where the
         * ramp ends keeps the chord on the model. */
        if (dir != gh->last_dir[j] && s->takeup_mm[j] > 0.0f) {
            float t = s->takeup_mm[j] / absf(d);
            if (t < 1.0f) {
                add_break(line->t_end, &line->pieces, t);
            }
        }
        /* The faces of the travel box the line crosses. */
        float faces[2] = {s->travel_lo_mm[j], s->travel_hi_mm[j]};
        for (unsigned f = 0; f < 2u; f++) {
            float t = (faces[f] - start[j]) / d;
            if (t > 1.0e-6f && t < 1.0f - 1.0e-6f) {
                add_break(line->t_end, &line->pieces, t);
            }
        }
    }
    if (line->pieces >= ABBE_GH_LINE_PIECES) { /* cannot happen: at most 3 x 3 breaks */
        line->pieces = ABBE_GH_LINE_PIECES - 1u;
    }
    line->t_end[line->pieces++] = 1.0f;
    float len = sqrt_pos(len2);
    float t0 = 0.0f;
    line->total = 0u;
    for (uint32_t k = 0; k < line->pieces; k++) {
        float rest = len * (line->t_end[k] - t0);
        uint32_t n = 1u;
        if (gh->seg_len_mm > 0.0f && rest > gh->seg_len_mm) {
            float f = rest / gh->seg_len_mm;
            n = (uint32_t)f;
            if ((float)n < f) {
                n++;
            }
        }
        line->n[k] = n;
        line->total += n;
        t0 = line->t_end[k];
    }
    line->piece = 0u;
    line->k = 0u;
    line->i = 0u;
    return line->total;
}

int abbe_gh_line_next(abbe_gh_line_t *line, float out[ABBE_AXES])
{
    if (line->i >= line->total) {
        return 0;
    }
    line->i++;
    if (line->i == line->total) {
        memcpy(out, line->end, sizeof line->end);
        return 1;
    }
    uint32_t p = line->piece;
    float t0 = p > 0u ? line->t_end[p - 1u] : 0.0f;
    line->k++;
    float t = t0 + (line->t_end[p] - t0) * (float)line->k / (float)line->n[p];
    if (line->k >= line->n[p]) { /* the piece's end: exactly the break */
        t = line->t_end[p];
        line->piece++;
        line->k = 0u;
    }
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        out[j] = line->start[j] + t * (line->end[j] - line->start[j]);
    }
    return 1;
}

/* ms since the previous segment end's thermal apply (0 at the first). */
static uint32_t thermal_elapsed(abbe_gh_t *gh)
{
    uint32_t dt = gh->thermal_applied ? gh->now_ms - gh->thermal_apply_ms : 0u;
    gh->thermal_apply_ms = gh->now_ms;
    gh->thermal_applied = 1u;
    return dt;
}

uint32_t abbe_gh_forward(abbe_gh_t *gh, const float cart[ABBE_AXES], float motor[ABBE_AXES])
{
    abbe_comp_output_t out;
    int8_t dir[ABBE_AXES];
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        float d = gh->have_last ? cart[j] - gh->last_cart[j] : 0.0f;
        /* NOLINTNEXTLINE(bugprone-narrowing-conversions): -1, 0 or 1 fit an int8_t */
        dir[j] = d > 0.0f ? 1 : (d < 0.0f ? -1 : 0);
    }
    const float *tref = gh->running != NO_SLOT ? gh->slot[gh->running].tref_c : gh->slot[0].tref_c;
#if ABBE_GH_FIXED_POINT
    abbe_comp_input_q_t in;
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        in.pos_nm[j] = mm_to_nm(cart[j]);
        in.temp_mdegc[j] = (int32_t)(tref[j] * 1000.0f + (tref[j] >= 0.0f ? 0.5f : -0.5f));
        in.dir[j] = dir[j];
    }
    in.fresh = 1u;
    in.axis_fault_mask = 0u;
    if (gh->thermal_on) {
        (void)abbe_comp_step_thermal_ms_q(&gh->comp, &gh->thermal, thermal_elapsed(gh), &in, &out);
    } else {
        (void)abbe_comp_step_q(&gh->comp, &in, &out);
    }
#else
    abbe_comp_input_f32_t in;
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        in.pos_mm[j] = cart[j];
        in.temp_c[j] = tref[j];
        in.dir[j] = dir[j];
    }
    in.fresh = 1u;
    in.axis_fault_mask = 0u;
    if (gh->thermal_on) {
        (void)abbe_comp_step_thermal_ms_f32(&gh->comp, &gh->thermal, thermal_elapsed(gh), &in, &out);
    } else {
        (void)abbe_comp_step_f32(&gh->comp, &in, &out);
    }
#endif
    if ((out.flags & ABBE_FLAG_MODEL_SWAPPED) && gh->pending != NO_SLOT) {
        gh->running = gh->pending;
        gh->pending = NO_SLOT;
        update_seg_len(gh);
        thermal_start(gh); /* the new table's block (if any) starts from its first sample */
    }
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        motor[j] = cart[j] + (float)out.corr_nm[j] * MM_PER_NM;
        gh->last_cart[j] = cart[j];
        gh->last_corr_nm[j] = out.corr_nm[j];
        if (dir[j] != 0) {
            gh->last_dir[j] = dir[j];
        }
    }
    gh->have_last = 1u;
    gh->flags = out.flags;
    gh->comp_state = out.state;
    gh->segments++;
    return out.flags;
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

void abbe_gh_set_position(abbe_gh_t *gh, const float cart[ABBE_AXES])
{
    memcpy(gh->last_cart, cart, sizeof gh->last_cart);
    gh->have_last = 1u;
}

static void put_le32(uint8_t *p, uint32_t v)
{
    for (unsigned k = 0; k < 4u; k++) {
        p[k] = (uint8_t)(v >> (8u * k));
    }
}

static uint32_t get_le32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}

void abbe_gh_store_header(uint8_t out[ABBE_GH_STORE_HEADER_BYTES], uint32_t size, uint32_t crc)
{
    put_le32(out, ABBE_GH_STORE_MAGIC);
    put_le32(out + 4, size);
    put_le32(out + 8, crc);
    put_le32(out + 12, abbe_crc32(0u, out, 12u));
}

abbe_gh_store_t abbe_gh_store_parse(const uint8_t in[ABBE_GH_STORE_HEADER_BYTES], uint32_t capacity,
                                    uint32_t *size, uint32_t *crc, const char **why)
{
    static const char *const none = "";
    *why = none;
    uint32_t magic = get_le32(in);
    if (magic == 0u || magic == 0xFFFFFFFFu) {
        return ABBE_GH_STORE_NONE; /* invalidated / erased */
    }
    if (magic != ABBE_GH_STORE_MAGIC) {
        *why = "no abbe table header (magic)";
        return ABBE_GH_STORE_CORRUPT;
    }
    if (get_le32(in + 12) != abbe_crc32(0u, in, 12u)) {
        *why = "header CRC-32 mismatch";
        return ABBE_GH_STORE_CORRUPT;
    }
    uint32_t n = get_le32(in + 4);
    uint32_t max = capacity < ABBE_GH_TABLE_MAX_BYTES ? capacity : ABBE_GH_TABLE_MAX_BYTES;
    if (n < 16u || n > max) {
        *why = "stored size out of range";
        return ABBE_GH_STORE_CORRUPT;
    }
    *size = n;
    *crc = get_le32(in + 8);
    return ABBE_GH_STORE_VALID;
}

const abbe_model_t *abbe_gh_model(const abbe_gh_t *gh)
{
    return abbe_comp_model(&gh->comp);
}

/* Append text / an unsigned decimal at w, never past end (the buffer's end: the
 * text is cut there); return the new end, NUL-terminated. w < end. */
static char *put_text(char *w, const char *end, const char *text)
{
    while (*text != '\0' && w + 1 < end) {
        *w = *text;
        w++;
        text++;
    }
    *w = '\0';
    return w;
}

static char *put_u32(char *w, const char *end, uint32_t v)
{
    char digits[10] = {0}; /* 4294967295: ten digits */
    unsigned n = 0u;
    do {
        digits[n] = (char)('0' + (char)(v % 10u));
        n++;
        v /= 10u;
    } while (v != 0u && n < 10u);
    while (n > 0u && w + 1 < end) {
        n--;
        *w = digits[n];
        w++;
    }
    *w = '\0';
    return w;
}

abbe_status_t abbe_gh_upload_begin(abbe_gh_t *gh, uint32_t size, uint32_t crc, const char **why)
{
    static const char *const none = "";
    *why = none;
    if (gh->pending != NO_SLOT) {
        *why = "the previous upload is not in use yet (it takes over at the next segment: move first)";
        return ABBE_E_ARG;
    }
    if (size < 16u || size > ABBE_GH_TABLE_MAX_BYTES) {
        /* "table of 9000 bytes: this build takes 16 to 8192 bytes" */
        char *w = gh->stage.why;
        const char *end = gh->stage.why + sizeof gh->stage.why;
        w = put_text(w, end, "table of ");
        w = put_u32(w, end, size);
        w = put_text(w, end, " bytes: this build takes 16 to ");
        w = put_u32(w, end, (uint32_t)ABBE_GH_TABLE_MAX_BYTES);
        (void)put_text(w, end, " bytes");
        *why = gh->stage.why;
        return ABBE_E_ARG;
    }
    gh->stage.slot = gh->running == 0u ? 1u : 0u;
    gh->stage.size = size;
    gh->stage.crc = crc;
    gh->stage.received = 0u;
    gh->stage.open = 1u;
    return ABBE_OK;
}

abbe_status_t abbe_gh_upload_data(abbe_gh_t *gh, uint32_t offset, const uint8_t *data, uint32_t n,
                                  const char **why)
{
    static const char *const none = "";
    *why = none;
    if (!gh->stage.open) {
        *why = "no upload open (begin with B,<size>,<crc32>)";
        return ABBE_E_ARG;
    }
    if (offset != gh->stage.received) {
        *why = "chunk out of order (offset is not the number of bytes received)";
        return ABBE_E_ARG;
    }
    /* the second test never binds (received <= size <= the slot's bytes): the
     * slot's bound stated where the copy is, for the proof (docs/proofs.md) */
    if (n > gh->stage.size - gh->stage.received || offset > ABBE_GH_TABLE_MAX_BYTES - n) {
        *why = "chunk runs past the announced size";
        return ABBE_E_ARG;
    }
    if (n != 0u) { /* an empty chunk at the end would pass memcpy a pointer past the slot */
        memcpy((uint8_t *)gh->slot[gh->stage.slot].blob + offset, data, n);
    }
    gh->stage.received += n;
    return ABBE_OK;
}

abbe_status_t abbe_gh_upload_commit(abbe_gh_t *gh, const char **why)
{
    static const char *const none = "";
    *why = none;
    if (!gh->stage.open) {
        *why = "no upload open (begin with B,<size>,<crc32>)";
        return ABBE_E_ARG;
    }
    gh->stage.open = 0u;
    abbe_gh_slot_t *s = &gh->slot[gh->stage.slot];
    if (gh->stage.received != gh->stage.size) {
        *why = "incomplete: fewer bytes received than announced";
        return ABBE_E_ARG;
    }
    if (abbe_crc32(0u, s->blob, gh->stage.size) != gh->stage.crc) {
        *why = "CRC-32 of the received bytes differs from the announced one";
        return ABBE_E_CRC;
    }
    /* Validate into the slot's model (on failure it is left untouched), derive
     * the segment length, then queue it: the compensator swaps at the start of
     * the next segment. The slot is not the running one; its model may be the
     * one that ran before, which nothing references any more. */
    abbe_status_t st = abbe_thermal_load(&s->model, &s->thermal, s->blob, gh->stage.size);
    if (st == ABBE_OK) {
        st = slot_prepare(s);
    }
    if (st == ABBE_OK) {
        st = abbe_comp_swap_model(&gh->comp, &s->model);
    }
    if (st != ABBE_OK) {
        s->loaded = 0u;
        *why = abbe_strerror(st);
        return st;
    }
    gh->pending = gh->stage.slot;
    update_seg_len(gh);
    return ABBE_OK;
}

void abbe_gh_upload_abort(abbe_gh_t *gh)
{
    gh->stage.open = 0u;
}
