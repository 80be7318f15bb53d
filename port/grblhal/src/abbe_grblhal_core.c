/* abbe grblHAL plugin core, the state machine: parameters and the segment
 * length in force, a table's preparation, start with a table, enable / fade /
 * fault, rehome, the forward transform of every segment end, and the thermal
 * block's clock and samples, over the abbe library's compensator
 * (include/abbe_grblhal_core.h). The curvature scan and the inverse are
 * abbe_grblhal_core_eval.c, the line segmentation abbe_grblhal_core_line.c,
 * the upload and the stored header abbe_grblhal_core_upload.c. Where a
 * function lives keeps its callers' machine code as it was before the split
 * (docs/architecture.md). C99, no heap, no I/O. */
#include <string.h>

#include "abbe_grblhal_core_private.h"

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

/* External (abbe_grblhal_core_private.h): the upload's commit prepares its slot too. */
abbe_status_t abbe_gh_slot_prepare(abbe_gh_slot_t *s)
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

/* External (abbe_grblhal_core_private.h): a committed upload changes it too. Next
 * to abbe_gh_segment_length, so its code is what it was before the split. */
void abbe_gh_update_seg_len(abbe_gh_t *gh)
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
            st = abbe_gh_slot_prepare(&gh->slot[0]);
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
    abbe_gh_update_seg_len(gh);
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
    abbe_gh_update_seg_len(gh);
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
        abbe_gh_update_seg_len(gh);
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
        abbe_gh_update_seg_len(gh);
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

void abbe_gh_set_position(abbe_gh_t *gh, const float cart[ABBE_AXES])
{
    memcpy(gh->last_cart, cart, sizeof gh->last_cart);
    gh->have_last = 1u;
}

const abbe_model_t *abbe_gh_model(const abbe_gh_t *gh)
{
    return abbe_comp_model(&gh->comp);
}
