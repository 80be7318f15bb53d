/* abbe: compensator cycle, fixed-point variant. */
#include "comp_core.h"

abbe_status_t abbe_comp_step_q(abbe_comp_t *comp, const abbe_comp_input_q_t *in, abbe_comp_output_t *out)
{
    if (comp == NULL || in == NULL || out == NULL) {
        return ABBE_E_ARG;
    }
    uint32_t flags = abbe_comp_begin(comp);
    int input_ok = in->fresh != 0u;
    int32_t error_nm[ABBE_AXES] = {0, 0, 0};
    int have_error = input_ok && comp->model != NULL;
    if (have_error) {
        abbe_comp_track_direction(comp, in->pos_nm, in->dir);
        abbe_input_q_t eval_in;
        abbe_error_q_t err;
        for (unsigned j = 0; j < ABBE_AXES; j++) {
            eval_in.pos_nm[j] = in->pos_nm[j];
            eval_in.dir_state_q30[j] = comp->dir_state_q30[j];
            eval_in.temp_mdegc[j] = in->temp_mdegc[j];
        }
        (void)abbe_error_eval_q(comp->model, &eval_in, &err); /* cannot fail: arguments checked */
        for (unsigned j = 0; j < ABBE_AXES; j++) {
            error_nm[j] = err.error_nm[j];
        }
        flags |= err.flags;
    }
    abbe_comp_finish(comp, input_ok, have_error ? error_nm : NULL, flags, in->axis_fault_mask, out);
    return ABBE_OK;
}
