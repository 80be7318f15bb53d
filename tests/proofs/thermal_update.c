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
#include <string.h>

#include "abbe/thermal.h"

static abbe_thermal_model_t thermal;
static abbe_thermal_state_t state;

#if defined(PROOF_ANY_BLOCK)
/* PROOF_ANY_BLOCK (thermal_any_q, thermal_any_f32): instead of the golden
 * table, ANY thermal block abbe_thermal_load accepts, the model built
 * directly within the invariants check_thermal establishes (thermal_load.c),
 * stated here as the runtime's preconditions: 1..17 inputs, each of either
 * kind, its reference, valid range and maximum step within the caps
 * (|ref|, |vmin|, |vmax| <= 2^20 milli-units, 1 <= step <= 2^21; vmin < vmax
 * is not imposed: a superset), a stuck time of 0..255 whole minutes and a
 * resolution of 0..65535 (0 without a stuck time); 1..5 channels, each any
 * output 0..4 (distinct outputs not imposed: a superset), 1..4 terms, each
 * reading an input below the input count, any time constant 0..2^31 ms, any
 * gain within +/-2^28, the channel's limit 1..2^30; the gap and fade times
 * 1..2^31 ms; the tool offset t_z any int32; the float twins as build_thermal
 * computes them. Or no block at all (0 inputs, 0 channels): the two cases
 * are kept apart (a partition each). These are the ranges of the ACSL
 * predicate thermal_model_ok (lib/src/thermal_acsl.h), the postcondition
 * stated for build_thermal (its proof is open: docs/proofs.md, "WP: the
 * thermal loader"); each field is drawn over the whole range that predicate
 * allows, independently, so every model satisfying it is among the
 * harness' models (and more: vmin >= vmax, repeated outputs). */
static void any_thermal(abbe_thermal_model_t *th)
{
    memset(th, 0, sizeof *th);
    th->tool_z_nm = Frama_C_int_interval(INT32_MIN, INT32_MAX);
    unsigned has_block, n_in, n_ch;
    has_block = Frama_C_unsigned_int_interval(0u, 1u);
    /*@ split has_block; */
    n_in = has_block ? Frama_C_unsigned_int_interval(1u, ABBE_THERMAL_MAX_INPUTS) : 0u;
    n_ch = has_block ? Frama_C_unsigned_int_interval(1u, ABBE_THERMAL_MAX_CHANNELS) : 0u;
    th->n_inputs = (uint8_t)n_in;
    th->n_channels = (uint8_t)n_ch;
    if (n_in == 0u) {
        return; /* no block */
    }
    th->max_gap_ms = Frama_C_unsigned_int_interval(1u, 0x80000000u);
    th->fade_ms = Frama_C_unsigned_int_interval(1u, 0x80000000u);
    for (unsigned k = 0; k < n_in; k++) {
        const unsigned minutes = Frama_C_unsigned_int_interval(0u, 255u);
        th->kind[k] = (uint8_t)Frama_C_unsigned_int_interval(ABBE_THERMAL_TEMPERATURE, ABBE_THERMAL_SPEED);
        th->ref_milli[k] = Frama_C_int_interval(-(1 << 20), 1 << 20);
        th->vmin_milli[k] = Frama_C_int_interval(-(1 << 20), 1 << 20);
        th->vmax_milli[k] = Frama_C_int_interval(-(1 << 20), 1 << 20);
        th->max_step_milli[k] = Frama_C_int_interval(1, 1 << 21);
        th->stuck_ms[k] = minutes * 60000u;
        th->stuck_res_milli[k] = minutes == 0u ? 0 : Frama_C_int_interval(0, 65535);
    }
    for (unsigned c = 0; c < n_ch; c++) {
        const unsigned n_terms = Frama_C_unsigned_int_interval(1u, ABBE_THERMAL_MAX_TERMS);
        th->output[c] = (uint8_t)Frama_C_unsigned_int_interval(ABBE_THERMAL_OUT_X, ABBE_THERMAL_OUT_B);
        th->n_terms[c] = (uint8_t)n_terms;
        th->limit[c] = Frama_C_int_interval(1, 1 << 30);
        for (unsigned k = 0; k < ABBE_THERMAL_MAX_TERMS; k++) {
            if (k < n_terms) {
                const unsigned input = Frama_C_unsigned_int_interval(0u, n_in - 1u);
                th->term_input[c][k] = (uint8_t)input;
                th->channel_inputs[c] |= 1u << input;
                th->tau_ms[c][k] = Frama_C_unsigned_int_interval(0u, 0x80000000u);
                th->gain_q16[c][k] = Frama_C_int_interval(-(1 << 28), 1 << 28);
            }
        }
    }
#if ABBE_WITH_F32
    /* the float twins, as build_thermal computes them */
    for (unsigned k = 0; k < n_in; k++) {
        float unit = th->kind[k] == ABBE_THERMAL_SPEED ? 1.0f : 0.001f;
        th->ref[k] = (float)th->ref_milli[k] * unit;
        th->vmin[k] = (float)th->vmin_milli[k] * unit;
        th->vmax[k] = (float)th->vmax_milli[k] * unit;
        th->max_step[k] = (float)th->max_step_milli[k] * unit;
        th->stuck_s[k] = (float)(th->stuck_ms[k] / 60000u) * 60.0f;
        th->stuck_res[k] = (float)th->stuck_res_milli[k] * unit;
        th->rise_scale[k] = th->kind[k] == ABBE_THERMAL_SPEED ? 0.001f : 1.0f;
    }
    for (unsigned c = 0; c < n_ch; c++) {
        th->limit_f[c] = (float)th->limit[c] * 0.001f;
        for (unsigned k = 0; k < th->n_terms[c]; k++) {
            th->tau_s[c][k] = (float)th->tau_ms[c][k] * 0.001f;
            th->gain[c][k] = (float)th->gain_q16[c][k] * (1.0f / 65536.0f);
        }
    }
    th->max_gap_s = (float)th->max_gap_ms * 0.001f;
    th->tool_z_mm = (float)th->tool_z_nm * 1e-6f;
#endif
}
#else
extern const uint8_t abbe_golden_thermal_blob[];
extern const uint32_t abbe_golden_thermal_blob_size;

static abbe_model_t model;
#endif

int main(void)
{
#if defined(PROOF_ANY_BLOCK)
    any_thermal(&thermal);
#else
    if (abbe_thermal_load(&model, &thermal, abbe_golden_thermal_blob, abbe_golden_thermal_blob_size) != ABBE_OK) {
        return 1;
    }
#endif
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
