/* Eva harness: the float evaluation (abbe_error_eval_f32) on the tables of
 * eval_q.c (PROOF_TABLES_H, PROOF_ANY_SCALARS, PROOF_ANY_COEFFICIENTS) at
 * every float input: every position, direction state and temperature: finite (default: then nothing
 * non-finite may arise either), or with -DPROOF_NONFINITE any 32 bits, NaN and
 * infinities included (analysed with -warn-special-float none: no memory or
 * integer error for those; that they are refused with ABBE_E_INPUT rests on
 * abbe_mm_to_nm_inline's test, checked on every float by hypotheses.c, and on
 * the unit tests; docs/proofs.md). */
#include "__fc_builtin.h"
#include <string.h>

#include "abbe/comp.h"
#include "abbe/error.h"

#include "tables.h"

static abbe_model_t model;
static abbe_comp_t comp;

#if defined(PROOF_ANY_SCALARS)
#include "any_scalars.h"
#endif

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
    /* any of the tables, each its own partition (tables.h) */
    proof_which = Frama_C_unsigned_int_interval(0u, PROOF_N_TABLES - 1u);
    const size_t size = proof_tables[proof_which].size;
    memcpy(blob, proof_tables[proof_which].bytes, size);
#if defined(PROOF_ANY_SCALARS)
    any_scalars((unsigned char *)blob);
#endif
#if defined(PROOF_ANY_COEFFICIENTS)
    any_coefficients((unsigned char *)blob);
#endif
    if (abbe_model_load(&model, blob, size) != ABBE_OK) {
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
#if !defined(PROOF_NONFINITE)
    /* the compensator's float cycle: any configuration, any number of cycles
     * of any input (positions and temperatures as above) */
    abbe_comp_config_t cfg;
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        cfg.warn_nm[j] = Frama_C_int_interval(INT32_MIN, INT32_MAX);
        cfg.limit_nm[j] = Frama_C_int_interval(INT32_MIN, INT32_MAX);
        cfg.rate_nm_per_cycle[j] = Frama_C_int_interval(INT32_MIN, INT32_MAX);
        cfg.axis_sign[j] = (int8_t)Frama_C_interval(INT8_MIN, INT8_MAX);
    }
    cfg.fade_cycles = (uint16_t)Frama_C_interval(0, 65535);
    cfg.stale_cycles = (uint16_t)Frama_C_interval(0, 65535);
    if (abbe_comp_init(&comp, &cfg, &model) != ABBE_OK || abbe_comp_enable(&comp) != ABBE_OK) {
        return 1;
    }
    while (Frama_C_nondet(0, 1)) {
        abbe_comp_input_f32_t cin;
        abbe_comp_output_t cout;
        for (unsigned j = 0; j < ABBE_AXES; j++) {
            cin.pos_mm[j] = any_f32();
            cin.temp_c[j] = Frama_C_float_interval(-1.0e6f, 1.0e6f);
            cin.dir[j] = (int8_t)Frama_C_interval(INT8_MIN, INT8_MAX);
        }
        cin.fresh = (uint8_t)Frama_C_interval(0, 255);
        cin.axis_fault_mask = (uint8_t)Frama_C_interval(0, 255);
        (void)abbe_comp_step_f32(&comp, &cin, &cout);
        if (Frama_C_nondet(0, 1)) {
            (void)abbe_comp_reset(&comp);
        }
    }
#endif
    return 0;
}
