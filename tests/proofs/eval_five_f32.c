/* Eva harness: the five-axis float evaluation (abbe_five_error_eval_f32) on
 * a five-axis table the loader accepted (PROOF_TABLE, a golden table of
 * tests/golden/golden_five.c, as in eval_five_q.c) at every joint position:
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

#define PROOF_STR2(x) #x
#define PROOF_STR(x) PROOF_STR2(x)
#include PROOF_STR(PROOF_TABLE)

static uint32_t blob[(sizeof table_bin + 3u) / 4u];
static abbe_five_model_t model;

#if defined(PROOF_NONFINITE)
/* any float32, NaN and the infinities included: any 32 bits */
static float any_f32(void)
{
    uint32_t bits = Frama_C_unsigned_int_interval(0u, UINT32_MAX);
    float f;
    memcpy(&f, &bits, sizeof f);
    return f;
}
static float any_temp(void)
{
    return any_f32();
}
#else
/* any finite float32 */
static float any_f32(void)
{
    return Frama_C_float_interval(-3.40282347e+38f, 3.40282347e+38f);
}
static float any_temp(void)
{
    return Frama_C_float_interval(-1.0e6f, 1.0e6f);
}
#endif

int main(void)
{
    memcpy(blob, table_bin, sizeof table_bin);
    if (abbe_five_model_load(&model, blob, sizeof table_bin) != ABBE_OK) {
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
