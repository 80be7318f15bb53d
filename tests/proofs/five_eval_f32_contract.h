/* The contracts of the five-axis float evaluation's two parts (five_eval_f32.c:
 * abbe_five_eval_f32_linear, abbe_five_eval_f32_rotary), as the compensator's
 * float cycle abbe_comp_step5_f32 calls them (comp_five_f32.c).
 * eval_five_any_f32 proves them: Eva checks each precondition at the call and
 * each postcondition at the return, the functions analysed as they are, on a
 * model of any layout (eval_five_any.c's builder) and every input of the
 * preconditions; eval_five_any_f32_caps the same on the loader's whole domain
 * (every accepted coefficient and location error: -DPROOF_ROT_CAPS).
 * comp_five_any_f32 runs the cycles on the caps' models with
 * both functions as these contracts (-eva-use-spec), checking the
 * preconditions at each call: the model domain is the same builder, the
 * inputs are the preconditions' (docs/proofs.md, "Five-axis: any layout").
 * The bound B = 10^30 (um, urad) is what abbe_comp_um_to_nm needs (x 1000
 * stays finite); an evaluation's actual outputs are far smaller. */
#ifndef PROOF_FIVE_EVAL_F32_CONTRACT_H
#define PROOF_FIVE_EVAL_F32_CONTRACT_H

#include "internal.h"

/*@ // the evaluation's outputs: finite, and within B = 10^30 um / urad
    predicate out_finite(abbe_five_error_f32_t *o) =
        \is_finite(o->error_um[0]) && \is_finite(o->error_um[1]) && \is_finite(o->error_um[2]) &&
        \is_finite(o->orient_urad[0]) && \is_finite(o->orient_urad[1]) && \is_finite(o->orient_urad[2]);
    predicate error_bounded(abbe_five_error_f32_t *o) =
        -1.0e30 <= o->error_um[0] <= 1.0e30 && -1.0e30 <= o->error_um[1] <= 1.0e30 &&
        -1.0e30 <= o->error_um[2] <= 1.0e30;
    predicate orient_bounded(abbe_five_error_f32_t *o) =
        -1.0e30 <= o->orient_urad[0] <= 1.0e30 && -1.0e30 <= o->orient_urad[1] <= 1.0e30 &&
        -1.0e30 <= o->orient_urad[2] <= 1.0e30;
 */

/*@ requires out: \valid(out);
    requires at: \valid(at + (0 .. 4));
    requires inputs: \valid_read(pos_mm + (0 .. 2)) && \valid_read(angle_deg + (0 .. 1)) &&
                     \valid_read(dir_state + (0 .. 2)) && \valid_read(temp_c + (0 .. 2));
    requires finite_pos: \is_finite(pos_mm[0]) && \is_finite(pos_mm[1]) && \is_finite(pos_mm[2]);
    requires finite_angle: \is_finite(angle_deg[0]) && \is_finite(angle_deg[1]);
    requires finite_dir: \is_finite(dir_state[0]) && \is_finite(dir_state[1]) && \is_finite(dir_state[2]);
    requires temp: -1.0e6 <= temp_c[0] <= 1.0e6 && -1.0e6 <= temp_c[1] <= 1.0e6 &&
                   -1.0e6 <= temp_c[2] <= 1.0e6;
    assigns out->error_um[0 .. 2], out->orient_urad[0 .. 2], out->flags, at[0 .. 4]
        \from pos_mm[0 .. 2], angle_deg[0 .. 1], dir_state[0 .. 2], temp_c[0 .. 2];
    ensures status: \result == ABBE_OK || \result == ABBE_E_INPUT;
    ensures init: \initialized(out->error_um + (0 .. 2)) && \initialized(out->orient_urad + (0 .. 2)) &&
                  \initialized(&out->flags);
    ensures at_init: \result == ABBE_OK ==> \initialized(at + (0 .. 4));
    ensures finite: out_finite(out);
    ensures error_um: error_bounded(out);
    ensures orient_urad: orient_bounded(out);
 */
abbe_status_t abbe_five_eval_f32_linear(const abbe_model_t *m, const float pos_mm[3], const float angle_deg[2],
                                        const float dir_state[3], const float temp_c[3], abbe_five_error_f32_t *out,
                                        int32_t at[ABBE_FIVE_AT]);

/*@ requires out: \valid(out);
    requires at: \valid_read(p + (0 .. 2)) && \valid_read(udeg + (0 .. 1)) &&
                 \initialized(p + (0 .. 2)) && \initialized(udeg + (0 .. 1));
    requires error_um: error_bounded(out);
    requires orient_urad: orient_bounded(out);
    assigns out->error_um[0 .. 2], out->orient_urad[0 .. 2]
        \from p[0 .. 2], udeg[0 .. 1], out->error_um[0 .. 2], out->orient_urad[0 .. 2];
    ensures finite: out_finite(out);
    ensures error_um: error_bounded(out);
    ensures orient_urad: orient_bounded(out);
 */
void abbe_five_eval_f32_rotary(const abbe_five_model_t *m5, const int32_t p[3], const int32_t udeg[2],
                               abbe_five_error_f32_t *out);

#endif /* PROOF_FIVE_EVAL_F32_CONTRACT_H */
