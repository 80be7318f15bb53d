/* Eva harness: the five-axis float evaluation (abbe_five_error_eval_f32) on
 * the tables of eval_five_q.c (PROOF_TABLES_H, PROOF_ANY_SCALARS) at every
 * joint position:
 * every finite linear position and angle, direction state, and every
 * temperature in [-10^6, 10^6] degC (as eval_f32.c: beyond, the refusal rests
 * on abbe_f32_temp_invalid's bit test); with -DPROOF_NONFINITE every input
 * any 32 bits, NaN and the infinities included (analysed with
 * -warn-special-float none: no memory or integer error for those; their
 * refusal with ABBE_E_INPUT rests on abbe_mm_to_nm_inline's test, checked on
 * every float by hypotheses.c, and on the unit tests; docs/proofs.md). */
#include "__fc_builtin.h"
#include <string.h>

#include "abbe/five_axis.h"

#include "any_inputs.h" /* any_f32, any_temp (PROOF_NONFINITE: any bits) */
#include "tables.h"

#if defined(PROOF_ANY_SCALARS)
#define PROOF_FIVE 1
#include "any_scalars.h"
#endif

static abbe_five_model_t model;

int main(void)
{
    /* any of the tables, each its own partition (tables.h) */
    proof_which = Frama_C_unsigned_int_interval(0u, PROOF_N_TABLES - 1u);
    const size_t size = proof_tables[proof_which].size;
    memcpy(blob, proof_tables[proof_which].bytes, size);
#if defined(PROOF_ANY_SCALARS)
    any_scalars((unsigned char *)blob);
    any_rotary_scalars((unsigned char *)blob);
#endif
    if (abbe_five_model_load(&model, blob, size) != ABBE_OK) {
        return 1;
    }
    abbe_five_input_f32_t in;
    abbe_five_error_f32_t out;
    for (unsigned j = 0; j < 3u; j++) {
        in.pos_mm[j] = any_f32();
        in.dir_state[j] = any_f32();
        in.temp_c[j] = any_temp();
    }
    in.angle_deg[0] = any_f32();
    in.angle_deg[1] = any_f32();
    (void)abbe_five_error_eval_f32(&model, &in, &out);
    return 0;
}
