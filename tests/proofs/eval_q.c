/* Eva harness: the fixed-point evaluation and the compensator's fixed-point
 * cycle on every table the loader accepts with the layout of one of the
 * golden tables of PROOF_TABLES_H (tests/proofs/tables.h; scripts/prove.sh
 * writes it from tests/golden): with PROOF_ANY_SCALARS any scalar field, with
 * PROOF_ANY_COEFFICIENTS any coefficients in a box (tests/proofs/any_scalars.h),
 * the real loader run on those bytes; at every position
 * (all of int32 nm, in and beyond the travel), every direction state and
 * every temperature; the compensator with any configuration, any number of
 * cycles of any input, resets in between (docs/proofs.md). */
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

static int32_t any_i32(void)
{
    return Frama_C_int_interval(INT32_MIN, INT32_MAX);
}

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
    /* the evaluation: every position, direction state and temperature */
    abbe_input_q_t in_q;
    abbe_error_q_t out_q;
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        in_q.pos_nm[j] = any_i32();
        in_q.dir_state_q30[j] = any_i32();
        in_q.temp_mdegc[j] = any_i32();
    }
    (void)abbe_error_eval_q(&model, &in_q, &out_q);
    /* the compensator: any configuration the init accepts, any number of
     * cycles of any fixed-point input */
    abbe_comp_config_t cfg;
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        cfg.warn_nm[j] = any_i32();
        cfg.limit_nm[j] = any_i32();
        cfg.rate_nm_per_cycle[j] = any_i32();
        cfg.axis_sign[j] = (int8_t)Frama_C_interval(INT8_MIN, INT8_MAX);
    }
    cfg.fade_cycles = (uint16_t)Frama_C_interval(0, 65535);
    cfg.stale_cycles = (uint16_t)Frama_C_interval(0, 65535);
    if (abbe_comp_init(&comp, &cfg, &model) != ABBE_OK || abbe_comp_enable(&comp) != ABBE_OK) {
        return 1;
    }
    while (Frama_C_nondet(0, 1)) {
        abbe_comp_input_q_t cin;
        abbe_comp_output_t cout;
        for (unsigned j = 0; j < ABBE_AXES; j++) {
            cin.pos_nm[j] = any_i32();
            cin.temp_mdegc[j] = any_i32();
            cin.dir[j] = (int8_t)Frama_C_interval(INT8_MIN, INT8_MAX);
        }
        cin.fresh = (uint8_t)Frama_C_interval(0, 255);
        cin.axis_fault_mask = (uint8_t)Frama_C_interval(0, 255);
        (void)abbe_comp_step_q(&comp, &cin, &cout);
        if (Frama_C_nondet(0, 1)) {
            (void)abbe_comp_reset(&comp);
        }
    }
    return 0;
}
