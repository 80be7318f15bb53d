/* Eva harness: the thermal runtime (thermal.c, thermal_q.c / thermal_f32.c)
 * on the golden format 1.3 table (tests/golden/golden_thermal.c, loaded by
 * abbe_thermal_load from its bytes): init, then any number of updates with
 * any sample values, any valid mask and any elapsed time, each followed by
 * the application to the tool tip, by apply() (one period per call) or, for
 * the whole run, by apply_ms() (any elapsed time per call). PROOF_Q: the fixed-point path, every int32
 * sample; otherwise the float path, every float bit pattern (NaN and the
 * infinities included: run with -warn-special-float none, every other kind of
 * alarm still counts). */
#include "__fc_builtin.h"
#include "abbe/thermal.h"

extern const uint8_t abbe_golden_thermal_blob[];
extern const uint32_t abbe_golden_thermal_blob_size;

static abbe_model_t model;
static abbe_thermal_model_t thermal;
static abbe_thermal_state_t state;

int main(void)
{
    if (abbe_thermal_load(&model, &thermal, abbe_golden_thermal_blob, abbe_golden_thermal_blob_size) != ABBE_OK) {
        return 1;
    }
#if defined(PROOF_Q)
    uint32_t period_us = Frama_C_unsigned_int_interval(0u, 0xFFFFFFFFu);
    if (abbe_thermal_init_q(&state, &thermal, period_us) != ABBE_OK) {
        return 2;
    }
    const int by_ms = Frama_C_interval(0, 1); /* a state is driven by one of the two */
    while (Frama_C_interval(0, 1)) {
        int32_t x[ABBE_THERMAL_MAX_INPUTS];
        Frama_C_make_unknown((char *)x, sizeof x);
        uint32_t mask = Frama_C_unsigned_int_interval(0u, 0xFFFFFFFFu);
        uint32_t dt_ms = Frama_C_unsigned_int_interval(0u, 0xFFFFFFFFu);
        (void)abbe_thermal_update_q(&state, x, mask, dt_ms);
        int32_t err[3];
        Frama_C_make_unknown((char *)err, sizeof err); /* any error it is added to */
        if (by_ms) {
            abbe_thermal_apply_ms_q(&state, err, Frama_C_unsigned_int_interval(0u, 0xFFFFFFFFu));
        } else {
            abbe_thermal_apply_q(&state, err);
        }
    }
#else
    float period_s;
    Frama_C_make_unknown((char *)&period_s, sizeof period_s);
    if (abbe_thermal_init_f32(&state, &thermal, period_s) != ABBE_OK) {
        return 2;
    }
    const int by_ms = Frama_C_interval(0, 1);
    while (Frama_C_interval(0, 1)) {
        float x[ABBE_THERMAL_MAX_INPUTS];
        Frama_C_make_unknown((char *)x, sizeof x);
        uint32_t mask = Frama_C_unsigned_int_interval(0u, 0xFFFFFFFFu);
        float dt_s;
        Frama_C_make_unknown((char *)&dt_s, sizeof dt_s);
        (void)abbe_thermal_update_f32(&state, x, mask, dt_s);
        float err[3] = {0.0f, 0.0f, 0.0f};
        if (by_ms) {
            abbe_thermal_apply_ms_f32(&state, err, Frama_C_unsigned_int_interval(0u, 0xFFFFFFFFu));
        } else {
            abbe_thermal_apply_f32(&state, err);
        }
    }
#endif
    return 0;
}
