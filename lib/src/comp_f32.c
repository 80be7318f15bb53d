/* abbe: compensator cycle, single-precision variant. The safety layer is the
 * integer one of comp.c; only the model evaluation is float. */
#include "comp_core.h"

#if !ABBE_WITH_F32
#error "this is the _f32 variant: compile it with ABBE_WITH_F32=1 (or leave it undefined), or leave the file out"
#endif

/* um -> nm, rounded and saturated (the error is bounded far below this anyway).
 * Also used by the five-axis cycle (comp_five_f32.c). */
int32_t abbe_comp_um_to_nm(float um, uint32_t *flags)
{
    float nm = um * 1000.0f;
    if (nm >= 2147483520.0f) { /* largest float below 2^31 */
        *flags |= ABBE_FLAG_SATURATED;
        return INT32_MAX;
    }
    if (nm <= -2147483520.0f) {
        *flags |= ABBE_FLAG_SATURATED;
        return -INT32_MAX;
    }
    return (int32_t)(nm + (nm >= 0.0f ? 0.5f : -0.5f));
}

abbe_status_t abbe_comp_step_f32(abbe_comp_t *comp, const abbe_comp_input_f32_t *in, abbe_comp_output_t *out)
{
    if (comp == NULL || in == NULL || out == NULL) {
        return ABBE_E_ARG;
    }
    uint32_t flags = abbe_comp_begin(comp);
    int input_ok = in->fresh != 0u;
    int32_t pos_nm[ABBE_AXES] = {0, 0, 0};
    for (unsigned j = 0; input_ok && j < ABBE_AXES; j++) {
        uint32_t ignored = 0; /* out-of-travel is reported by the evaluation below */
        input_ok = abbe_mm_to_nm_f32(in->pos_mm[j], &pos_nm[j], &ignored) == ABBE_OK;
    }
    int32_t error_nm[ABBE_AXES];
    int have_error = 0;
    if (input_ok && comp->model != NULL) {
        abbe_comp_track_direction(comp, pos_nm, in->dir);
        abbe_input_f32_t eval_in;
        abbe_error_f32_t eval_out;
        for (unsigned j = 0; j < ABBE_AXES; j++) {
            eval_in.pos_mm[j] = in->pos_mm[j];
            eval_in.dir_state[j] = (float)comp->dir_state_q30[j] * 9.31322574615478515625e-10f; /* 2^-30 */
            eval_in.temp_c[j] = in->temp_c[j];
        }
        /* NaN temperature or direction state: a bad input like a NaN position */
        have_error = abbe_eval_f32_core(comp->model, &eval_in, &eval_out) == ABBE_OK;
        input_ok = have_error;
        for (unsigned j = 0; have_error && j < ABBE_AXES; j++) {
            error_nm[j] = abbe_comp_um_to_nm(eval_out.error_um[j], &flags);
        }
        if (have_error) {
            flags |= eval_out.flags;
        }
    }
    abbe_comp_finish(comp, input_ok, have_error ? error_nm : NULL, flags, in->axis_fault_mask, out);
    return ABBE_OK;
}
