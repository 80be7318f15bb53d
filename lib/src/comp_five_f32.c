/* abbe: compensator cycle with a five-axis model, single precision. The
 * safety layer is comp.c's; the evaluation is abbe_five_error_eval_f32. */
#include "comp_core.h"

#if !ABBE_WITH_F32
#error "this is the _f32 variant: compile it with ABBE_WITH_F32=1 (or leave it undefined), or leave the file out"
#endif

abbe_status_t abbe_comp_step5_f32(abbe_comp_t *comp, const abbe_comp_input5_f32_t *in, abbe_comp_output5_t *out)
{
    if (comp == NULL || in == NULL || out == NULL) {
        return ABBE_E_ARG;
    }
    uint32_t flags = abbe_comp_begin(comp);
    int input_ok = in->lin.fresh != 0u;
    /* the positions in nm, then the angles in micro-degrees (the evaluation's at), the
     * evaluation's output and the direction states in the compensator's working memory,
     * not on the stack: bench/results.md, section 11 */
    int32_t *pos_nm = comp->scratch.five_f32.at;
    for (unsigned j = 0; input_ok && j < ABBE_AXES; j++) {
        uint32_t ignored = 0; /* out-of-travel is reported by the evaluation below */
        /* inline: the five-axis image then holds no out-of-line copy (64 B less flash,
         * 8 B less stack: bench/results.md, section 11) */
        input_ok = abbe_mm_to_nm_inline(in->lin.pos_mm[j], &pos_nm[j], &ignored) == 0u;
    }
    int32_t *error_nm = comp->scratch.five_f32.error_nm;
    int have_error = 0;
    abbe_five_error_f32_t *eval_out = &comp->scratch.five_f32.eval;
    out->orient_nrad[0] = out->orient_nrad[1] = out->orient_nrad[2] = 0;
    if (input_ok && comp->model != NULL) {
        abbe_comp_track_direction(comp, pos_nm, in->lin.dir);
        float *dir_state = comp->scratch.five_f32.dir_state;
        for (unsigned j = 0; j < ABBE_AXES; j++) {
            dir_state[j] = (float)comp->dir_state_q30[j] * 9.31322574615478515625e-10f; /* 2^-30 */
        }
        /* a 3-axis model: its linear error (orientation 0); the angles must still be finite.
         * The positions in nm again into pos_nm (the same conversion), then the angles. Two
         * calls: the linear axes' frames and the rotary axes' are never on the stack together. */
        have_error = abbe_five_eval_f32_linear(comp->model, in->lin.pos_mm, in->angle_deg, dir_state, in->lin.temp_c,
                                               eval_out, pos_nm) == ABBE_OK;
        if (have_error != 0) {
            abbe_five_eval_f32_rotary(abbe_comp_five_model(comp), pos_nm, &pos_nm[ABBE_AXES], eval_out);
            for (unsigned j = 0; j < ABBE_AXES; j++) {
                error_nm[j] = abbe_comp_um_to_nm(eval_out->error_um[j], &flags);
                out->orient_nrad[j] = abbe_comp_um_to_nm(eval_out->orient_urad[j], &flags); /* x 1000: urad -> nrad */
            }
            flags |= eval_out->flags;
        }
        input_ok = have_error;
    }
    abbe_comp_finish(comp, input_ok, have_error ? error_nm : NULL, flags, in->lin.axis_fault_mask, &out->lin);
    return ABBE_OK;
}
