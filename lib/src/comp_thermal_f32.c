/* abbe: compensator cycle with the thermal block, single precision
 * (abbe/thermal.h); see comp_thermal_q.c. */
#include "abbe/thermal.h"
#include "comp_core.h"

static inline abbe_status_t comp_step_thermal_f32(abbe_comp_t *comp, abbe_thermal_state_t *thermal,
                                                  const abbe_comp_input_f32_t *in, abbe_comp_output_t *out, int timed,
                                                  uint32_t elapsed_ms)
{
    if (comp == NULL || in == NULL || out == NULL) {
        return ABBE_E_ARG;
    }
    uint32_t flags = abbe_comp_begin(comp);
    int input_ok = in->fresh != 0u;
    int32_t pos_nm[ABBE_AXES] = {0, 0, 0};
    for (unsigned j = 0; input_ok && j < ABBE_AXES; j++) {
        uint32_t ignored = 0;
        input_ok = abbe_mm_to_nm_f32(in->pos_mm[j], &pos_nm[j], &ignored) == ABBE_OK;
    }
    int32_t error_nm[ABBE_AXES];
    int have_error = 0;
    float th[ABBE_AXES] = {0.0f, 0.0f, 0.0f};
    if (thermal != NULL && thermal->model != NULL) {
        if (timed) {
            abbe_thermal_apply_ms_f32(thermal, th, elapsed_ms);
        } else {
            abbe_thermal_apply_f32(thermal, th); /* every cycle: its fades and watchdog run on */
        }
    }
    if (input_ok && comp->model != NULL) {
        abbe_comp_track_direction(comp, pos_nm, in->dir);
        abbe_input_f32_t eval_in;
        abbe_error_f32_t eval_out;
        for (unsigned j = 0; j < ABBE_AXES; j++) {
            eval_in.pos_mm[j] = in->pos_mm[j];
            eval_in.dir_state[j] = (float)comp->dir_state_q30[j] * 9.31322574615478515625e-10f; /* 2^-30 */
            eval_in.temp_c[j] = in->temp_c[j];
        }
        have_error = abbe_eval_f32_core(comp->model, &eval_in, &eval_out) == ABBE_OK;
        input_ok = have_error;
        for (unsigned j = 0; have_error && j < ABBE_AXES; j++) {
            error_nm[j] = abbe_comp_um_to_nm(eval_out.error_um[j] + th[j], &flags);
        }
        if (have_error) {
            flags |= eval_out.flags;
        }
    }
    abbe_comp_finish(comp, input_ok, have_error ? error_nm : NULL, flags, in->axis_fault_mask, out);
    return ABBE_OK;
}

abbe_status_t abbe_comp_step_thermal_f32(abbe_comp_t *comp, abbe_thermal_state_t *thermal,
                                         const abbe_comp_input_f32_t *in, abbe_comp_output_t *out)
{
    return comp_step_thermal_f32(comp, thermal, in, out, 0, 0u);
}

abbe_status_t abbe_comp_step_thermal_ms_f32(abbe_comp_t *comp, abbe_thermal_state_t *thermal, uint32_t elapsed_ms,
                                            const abbe_comp_input_f32_t *in, abbe_comp_output_t *out)
{
    return comp_step_thermal_f32(comp, thermal, in, out, 1, elapsed_ms);
}
