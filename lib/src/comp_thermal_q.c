/* abbe: compensator cycle with the thermal block, fixed-point variant
 * (abbe/thermal.h). abbe_comp_step_q plus abbe_thermal_apply_q on the error
 * before the safety layer: a separate function, so a firmware without a
 * thermal block keeps abbe_comp_step_q's cost and flash unchanged. */
#include "abbe/thermal.h"
#include "comp_core.h"

/* timed: advance the thermal fades and watchdog by elapsed_ms (apply_ms),
 * else by one period (apply); a constant at each call, so each public
 * function compiles to one path. */
static inline abbe_status_t comp_step_thermal_q(abbe_comp_t *comp, abbe_thermal_state_t *thermal,
                                                const abbe_comp_input_q_t *in, abbe_comp_output_t *out, int timed,
                                                uint32_t elapsed_ms)
{
    if (comp == NULL || in == NULL || out == NULL) {
        return ABBE_E_ARG;
    }
    uint32_t flags = abbe_comp_begin(comp);
    int input_ok = in->fresh != 0u;
    int32_t *error_nm = &comp->scratch.q[ABBE_AXES * ABBE_TERMS];
    int have_error = input_ok && comp->model != NULL;
    if (have_error) {
        abbe_comp_track_direction(comp, in->pos_nm, in->dir);
        flags |= abbe_eval_q_core(comp->model, in->pos_nm, comp->dir_state_q30, in->temp_mdegc, comp->scratch.q,
                                  error_nm);
    }
    if (thermal != NULL && thermal->model != NULL) {
        int32_t th[ABBE_AXES] = {0, 0, 0};
        if (timed) {
            abbe_thermal_apply_ms_q(thermal, th, elapsed_ms);
        } else {
            abbe_thermal_apply_q(thermal, th); /* every cycle: its fades and watchdog run on */
        }
        for (unsigned j = 0; have_error && j < ABBE_AXES; j++) {
            error_nm[j] = abbe_sat_i32((int64_t)error_nm[j] + th[j], &flags);
        }
    }
    abbe_comp_finish(comp, input_ok, have_error ? error_nm : NULL, flags, in->axis_fault_mask, out);
    return ABBE_OK;
}

abbe_status_t abbe_comp_step_thermal_q(abbe_comp_t *comp, abbe_thermal_state_t *thermal, const abbe_comp_input_q_t *in,
                                       abbe_comp_output_t *out)
{
    return comp_step_thermal_q(comp, thermal, in, out, 0, 0u);
}

abbe_status_t abbe_comp_step_thermal_ms_q(abbe_comp_t *comp, abbe_thermal_state_t *thermal, uint32_t elapsed_ms,
                                          const abbe_comp_input_q_t *in, abbe_comp_output_t *out)
{
    return comp_step_thermal_q(comp, thermal, in, out, 1, elapsed_ms);
}
