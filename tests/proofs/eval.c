/* Eva harness: the evaluators and the compensator on a table the loader
 * accepted (table_paper.h, a C array of its bytes that scripts/prove.sh
 * generates from examples/paper_table/model.bin), at every position (all of
 * int32 nm, in and beyond the travel; float mm over +/-PROOF_MM), every
 * direction state and every temperature (docs/proofs.md). */
#include "__fc_builtin.h"
#include <string.h>

#include "abbe/comp.h"
#include "abbe/error.h"

#include "table_paper.h" /* unsigned char table_bin[]; unsigned int table_bin_len; (xxd -i, written by scripts/prove.sh --open into build-proofs/) */

#ifndef PROOF_MM
#define PROOF_MM 3000.0f
#endif

static uint32_t blob[(sizeof table_bin + 3u) / 4u];
static abbe_model_t model;
static abbe_comp_t comp;

static int32_t any_i32(void)
{
    return Frama_C_int_interval(INT32_MIN, INT32_MAX);
}

static float any_f32(float lo, float hi)
{
    return Frama_C_float_interval(lo, hi);
}

int main(void)
{
    memcpy(blob, table_bin, sizeof table_bin);
    if (abbe_model_load(&model, blob, sizeof table_bin) != ABBE_OK) {
        return 1;
    }
    /* _q: every position, direction state and temperature */
    abbe_input_q_t in_q;
    abbe_error_q_t out_q;
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        in_q.pos_nm[j] = any_i32();
        in_q.dir_state_q30[j] = any_i32();
        in_q.temp_mdegc[j] = any_i32();
    }
    (void)abbe_error_eval_q(&model, &in_q, &out_q);
    /* _f32: every finite position, direction state and temperature */
    abbe_input_f32_t in_f;
    abbe_error_f32_t out_f;
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        in_f.pos_mm[j] = any_f32(-PROOF_MM, PROOF_MM);
        in_f.dir_state[j] = any_f32(-2.0f, 2.0f);
        in_f.temp_c[j] = any_f32(-300.0f, 300.0f);
    }
    (void)abbe_error_eval_f32(&model, &in_f, &out_f);
    /* the compensator: any number of cycles of any fixed-point input */
    abbe_comp_config_t cfg;
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        cfg.warn_nm[j] = Frama_C_int_interval(1, INT32_MAX);
        cfg.limit_nm[j] = Frama_C_int_interval(cfg.warn_nm[j], INT32_MAX);
        cfg.rate_nm_per_cycle[j] = Frama_C_int_interval(1, INT32_MAX);
        cfg.axis_sign[j] = (int8_t)(Frama_C_nondet(0, 1) ? 1 : -1);
    }
    cfg.fade_cycles = (uint16_t)Frama_C_interval(1, 65535);
    cfg.stale_cycles = (uint16_t)Frama_C_interval(1, 65535);
    if (abbe_comp_init(&comp, &cfg, &model) != ABBE_OK || abbe_comp_enable(&comp) != ABBE_OK) {
        return 1;
    }
    while (Frama_C_nondet(0, 1)) {
        abbe_comp_input_q_t cin;
        abbe_comp_output_t cout;
        for (unsigned j = 0; j < ABBE_AXES; j++) {
            cin.pos_nm[j] = any_i32();
            cin.temp_mdegc[j] = any_i32();
            cin.dir[j] = (int8_t)Frama_C_interval(-1, 1);
        }
        cin.fresh = (uint8_t)Frama_C_interval(0, 1);
        cin.axis_fault_mask = (uint8_t)Frama_C_interval(0, 7);
        (void)abbe_comp_step_q(&comp, &cin, &cout);
        if (Frama_C_nondet(0, 1)) {
            (void)abbe_comp_reset(&comp);
        }
    }
    return 0;
}
