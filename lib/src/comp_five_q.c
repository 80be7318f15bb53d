/* abbe: compensator cycle with a five-axis model, fixed point. */
#include "comp_core.h"

abbe_status_t abbe_comp_step5_q(abbe_comp_t *comp, const abbe_comp_input5_q_t *in, abbe_comp_output5_t *out)
{
    if (comp == NULL || in == NULL || out == NULL) {
        return ABBE_E_ARG;
    }
    uint32_t flags = abbe_comp_begin(comp);
    int input_ok = in->lin.fresh != 0u;
    int32_t *error_nm = &comp->scratch.q[ABBE_AXES * ABBE_TERMS];
    int have_error = input_ok && comp->model != NULL;
    out->orient_nrad[0] = out->orient_nrad[1] = out->orient_nrad[2] = 0;
    if (have_error) {
        abbe_comp_track_direction(comp, in->lin.pos_nm, in->lin.dir);
        const abbe_five_model_t *five = abbe_comp_five_model(comp);
        if (five != NULL) {
            flags |= abbe_five_eval_q_core(five, in->lin.pos_nm, in->angle_udeg, comp->dir_state_q30,
                                           in->lin.temp_mdegc, comp->scratch.q, error_nm, out->orient_nrad);
        } else {
            flags |= abbe_eval_q_core(comp->model, in->lin.pos_nm, comp->dir_state_q30, in->lin.temp_mdegc,
                                      comp->scratch.q, error_nm);
        }
    }
    abbe_comp_finish(comp, input_ok, have_error ? error_nm : NULL, flags, in->lin.axis_fault_mask, &out->lin);
    return ABBE_OK;
}
