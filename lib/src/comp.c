/* abbe: compensator state machine, integer only, shared by both variants.
 *
 * Per axis a gain (Q16) ramps toward 1 while the compensator is enabled, not
 * faulted, not stale, has a model and the axis is healthy, and toward 0
 * otherwise; the output then follows gain * target within the rate limit. So
 * every way a correction appears or disappears is a ramp, never a step.
 */
#include "comp_core.h"

#define GAIN_ONE 65536u

static int config_ok(const abbe_comp_config_t *cfg)
{
    if (cfg->fade_cycles < 1u || cfg->stale_cycles < 1u) {
        return 0;
    }
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        if (cfg->warn_nm[j] <= 0 || cfg->limit_nm[j] < cfg->warn_nm[j] ||
            cfg->rate_nm_per_cycle[j] <= 0 || (cfg->axis_sign[j] != 1 && cfg->axis_sign[j] != -1)) {
            return 0;
        }
    }
    return 1;
}

abbe_status_t abbe_comp_init(abbe_comp_t *comp, const abbe_comp_config_t *cfg, const abbe_model_t *model)
{
    if (comp == NULL || cfg == NULL || !config_ok(cfg)) {
        return ABBE_E_ARG;
    }
    memset(comp, 0, sizeof *comp);
    comp->cfg = *cfg;
    comp->model = model;
    /* ceil so that fade_cycles steps always reach a full ramp */
    comp->gain_step_q16 = (GAIN_ONE + cfg->fade_cycles - 1u) / cfg->fade_cycles;
    return ABBE_OK;
}

abbe_status_t abbe_comp_set_config(abbe_comp_t *comp, const abbe_comp_config_t *cfg)
{
    if (comp == NULL || cfg == NULL || !config_ok(cfg)) {
        return ABBE_E_ARG;
    }
    comp->cfg = *cfg;
    comp->gain_step_q16 = (GAIN_ONE + cfg->fade_cycles - 1u) / cfg->fade_cycles;
    return ABBE_OK;
}

abbe_status_t abbe_comp_enable(abbe_comp_t *comp)
{
    if (comp == NULL) {
        return ABBE_E_ARG;
    }
    comp->enabled = 1;
    return ABBE_OK;
}

abbe_status_t abbe_comp_disable(abbe_comp_t *comp)
{
    if (comp == NULL) {
        return ABBE_E_ARG;
    }
    comp->enabled = 0;
    return ABBE_OK;
}

abbe_status_t abbe_comp_reset(abbe_comp_t *comp)
{
    if (comp == NULL) {
        return ABBE_E_ARG;
    }
    comp->fault = 0;
    comp->enabled = 0;
    return ABBE_OK;
}

abbe_status_t abbe_comp_swap_model(abbe_comp_t *comp, const abbe_model_t *model)
{
    if (comp == NULL || model == NULL) {
        return ABBE_E_ARG;
    }
    comp->pending = model;
    return ABBE_OK;
}

abbe_status_t abbe_comp_load_model(abbe_comp_t *comp, abbe_model_t *slot, const void *blob, size_t size)
{
    if (comp == NULL || slot == NULL || slot == comp->model || slot == comp->pending) {
        return ABBE_E_ARG;
    }
    abbe_status_t st = abbe_model_load(slot, blob, size); /* leaves *slot untouched on failure */
    if (st == ABBE_OK) {
        comp->pending = slot;
    }
    return st;
}

const abbe_model_t *abbe_comp_model(const abbe_comp_t *comp)
{
    return comp != NULL ? comp->model : NULL;
}

size_t abbe_comp_sizeof(void)
{
    return sizeof(abbe_comp_t);
}

abbe_comp_stats_t abbe_comp_stats(const abbe_comp_t *comp)
{
    abbe_comp_stats_t none = {0, 0, 0, 0, 0, 0};
    return comp != NULL ? comp->stats : none;
}

uint32_t abbe_comp_begin(abbe_comp_t *comp)
{
    uint32_t flags = 0;
    comp->stats.cycles++;
    if (comp->pending != NULL) {
        comp->model = comp->pending;
        comp->pending = NULL;
        comp->stats.model_swaps++;
        flags |= ABBE_FLAG_MODEL_SWAPPED;
    }
    if (comp->model == NULL) {
        flags |= ABBE_FLAG_NO_MODEL;
    }
    return flags;
}

void abbe_comp_track_direction(abbe_comp_t *comp, const int32_t pos_nm[ABBE_AXES], const int8_t dir[ABBE_AXES])
{
    const abbe_model_t *m = comp->model;
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        if (m != NULL && (m->features & ABBE_FEATURE_BACKLASH) && comp->have_pos && dir[j] != 0) {
            int64_t d = (int64_t)pos_nm[j] - comp->last_pos_nm[j];
            uint64_t dist = (uint64_t)(d < 0 ? -d : d);
            int32_t step = abbe_arg_takeup_q30(&m->axis[j], dist > UINT32_MAX ? UINT32_MAX : (uint32_t)dist);
            int64_t s = (int64_t)comp->dir_state_q30[j] + (dir[j] > 0 ? step : -(int64_t)step);
            comp->dir_state_q30[j] = (int32_t)abbe_clamp_i64(s, -ABBE_Q30_ONE, ABBE_Q30_ONE);
        }
        comp->last_pos_nm[j] = pos_nm[j];
    }
    comp->have_pos = 1;
}

static uint32_t ramp_gain(uint32_t gain, uint32_t step, int up)
{
    /* gain, step <= GAIN_ONE; each result a variable that its test bounds
     * where it is returned (the proofs: docs/proofs.md, "Signed downcasts") */
    if (up) {
        const uint32_t g = gain + step;
        return g >= GAIN_ONE ? GAIN_ONE : g;
    }
    const int32_t g = (int32_t)gain - (int32_t)step;
    return g > 0 ? (uint32_t)g : 0u;
}

void abbe_comp_finish(abbe_comp_t *comp, int input_ok, const int32_t *error_nm, uint32_t flags,
                      uint8_t axis_fault_mask, abbe_comp_output_t *out)
{
    const abbe_comp_config_t *cfg = &comp->cfg;

    if (error_nm != NULL) {
        for (unsigned j = 0; j < ABBE_AXES; j++) {
            /* -sign * error within +/-INT32_MAX, in 32 bits: only INT32_MIN needs care */
            int32_t e = error_nm[j] == INT32_MIN ? -INT32_MAX : error_nm[j];
            comp->target_nm[j] = cfg->axis_sign[j] > 0 ? -e : e;
        }
        comp->eval_flags = flags & (ABBE_FLAG_OUT_OF_TRAVEL | ABBE_FLAG_SATURATED);
    }
    if (input_ok) {
        comp->stale_count = 0;
        comp->stale = 0;
    } else {
        comp->stats.invalid_inputs++;
        flags |= ABBE_FLAG_INPUT_INVALID;
        if (comp->stale_count < UINT16_MAX) {
            comp->stale_count++;
        }
        if (!comp->stale && comp->stale_count >= cfg->stale_cycles) {
            comp->stale = 1;
            comp->stats.stale_events++;
        }
    }
    flags |= comp->eval_flags;
    if (comp->stale) {
        flags |= ABBE_FLAG_STALE;
    }

    for (unsigned j = 0; j < ABBE_AXES; j++) {
        const int32_t t = comp->target_nm[j]; /* within +/-INT32_MAX: |t| fits */
        const int32_t magnitude = t < 0 ? -t : t;
        if (magnitude > cfg->warn_nm[j]) {
            flags |= ABBE_FLAG_WARN;
        }
        if (magnitude > cfg->limit_nm[j] && comp->model != NULL && !comp->fault) {
            comp->fault = 1;
            comp->stats.limit_trips++;
            /* Fade out from the output as it is, never toward the target that
             * tripped the limit: it is beyond the limit by definition. */
            for (unsigned k = 0; k < ABBE_AXES; k++) {
                comp->fault_from_nm[k] = comp->out_nm[k];
                comp->gain_q16[k] = GAIN_ONE;
            }
        }
    }
    if (comp->fault) {
        flags |= ABBE_FLAG_LIMIT;
    }
    if (axis_fault_mask & 0x7u) {
        flags |= ABBE_FLAG_AXIS_FAULT;
    }

    int fading = 0, clipped = 0;
    int run = comp->enabled && !comp->fault && !comp->stale && comp->model != NULL;
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        int up = run && !(((unsigned)axis_fault_mask >> j) & 1u);
        comp->gain_q16[j] = ramp_gain(comp->gain_q16[j], comp->gain_step_q16, up);
        fading |= comp->gain_q16[j] > 0u && comp->gain_q16[j] < GAIN_ONE;

        /* Faulted: the held output fades to zero (monotonic, within the rate
         * limit); otherwise the output follows gain * target. */
        int32_t base = comp->fault ? comp->fault_from_nm[j] : comp->target_nm[j];
        int64_t desired = abbe_shr_round((int64_t)base * comp->gain_q16[j], 16u);
        /* within rate of the previous output: desired held to [lo, hi]. The
         * result lies between the output and desired, both int32 (the gain is
         * at most 1), and is taken from a bound only where desired is beyond
         * it, which states that range for the conversion to int32
         * (docs/proofs.md, "Signed downcasts") */
        int64_t rate = cfg->rate_nm_per_cycle[j];
        const int64_t lo = (int64_t)comp->out_nm[j] - rate;
        const int64_t hi = (int64_t)comp->out_nm[j] + rate;
        int64_t next = desired;
        if (desired > hi) {
            next = hi;
            clipped = 1;
        }
        if (desired < lo) { /* lo < hi: never both */
            next = lo;
            clipped = 1;
        }
        comp->out_nm[j] = (int32_t)next;
        out->corr_nm[j] = comp->out_nm[j];
        out->target_nm[j] = comp->target_nm[j];
    }
    if (fading) {
        flags |= ABBE_FLAG_FADING;
    }
    if (clipped) {
        flags |= ABBE_FLAG_RATE_LIMITED;
        comp->stats.rate_limited++;
    }
    out->flags = flags;
    out->state = comp->fault ? ABBE_COMP_FAULT : (comp->enabled ? ABBE_COMP_ON : ABBE_COMP_OFF);
}
