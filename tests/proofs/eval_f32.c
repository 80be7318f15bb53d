/* Eva harness: the float evaluation (abbe_error_eval_f32) on a table the
 * loader accepted (PROOF_TABLE, as in eval_q.c) at every float input: every
 * position, direction state and temperature: finite (default: then nothing
 * non-finite may arise either), or with -DPROOF_NONFINITE any 32 bits, NaN and
 * infinities included (analysed with -warn-special-float none: no memory or
 * integer error for those; that they are refused with ABBE_E_INPUT rests on
 * abbe_mm_to_nm_inline's test, checked on every float by hypotheses.c, and on
 * the unit tests; docs/proofs.md). */
#include "__fc_builtin.h"
#include <string.h>

#include "abbe/error.h"

#define PROOF_STR2(x) #x
#define PROOF_STR(x) PROOF_STR2(x)
#include PROOF_STR(PROOF_TABLE)

static uint32_t blob[(sizeof table_bin + 3u) / 4u];
static abbe_model_t model;

#if defined(PROOF_NONFINITE)
/* any float32, NaN and the infinities included: any 32 bits */
static float any_f32(void)
{
    uint32_t bits = Frama_C_unsigned_int_interval(0u, UINT32_MAX);
    float f;
    memcpy(&f, &bits, sizeof f);
    return f;
}
#else
/* any finite float32 */
static float any_f32(void)
{
    return Frama_C_float_interval(-3.40282347e+38f, 3.40282347e+38f);
}
#endif

int main(void)
{
    memcpy(blob, table_bin, sizeof table_bin);
    if (abbe_model_load(&model, blob, sizeof table_bin) != ABBE_OK) {
        return 1;
    }
    abbe_input_f32_t in;
    abbe_error_f32_t out;
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        in.pos_mm[j] = any_f32();
        in.dir_state[j] = any_f32();
#if defined(PROOF_NONFINITE)
        in.temp_c[j] = any_f32();
#else
        /* |T| <= 10^6 degC (the _q variant's clamp of dT, 2^30 mK, is about
         * the same): beyond, the float thermal term overflows to infinity
         * (docs/proofs.md, "Not proven yet") */
        in.temp_c[j] = Frama_C_float_interval(-1.0e6f, 1.0e6f);
#endif
    }
    (void)abbe_error_eval_f32(&model, &in, &out);
    return 0;
}
