/* abbe: compensator cycle, fixed-point variant. */
#include "comp_core.h"

abbe_status_t abbe_comp_step_q(abbe_comp_t *comp, const abbe_comp_input_q_t *in, abbe_comp_output_t *out)
{
    if (comp == NULL || in == NULL || out == NULL) {
        return ABBE_E_ARG;
    }
    uint32_t flags = abbe_comp_begin(comp);
    int input_ok = in->fresh != 0u;
    /* the evaluation reads the direction states in place and works in the
     * compensator's scratch: no copies on the stack */
    int32_t *error_nm = &comp->scratch.q[ABBE_AXES * ABBE_TERMS];
    int have_error = input_ok && comp->model != NULL;
    if (have_error) {
        abbe_comp_track_direction(comp, in->pos_nm, in->dir);
        flags |= abbe_eval_q_core(comp->model, in->pos_nm, comp->dir_state_q30, in->temp_mdegc, comp->scratch.q,
                                  error_nm);
    }
    abbe_comp_finish(comp, input_ok, have_error ? error_nm : NULL, flags, in->axis_fault_mask, out);
    return ABBE_OK;
}
