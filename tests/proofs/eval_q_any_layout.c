/* Eva harness: the fixed-point evaluation abbe_error_eval_q and the
 * compensator's fixed-point cycle (as eval_q.c) on a model of ANY layout the
 * loader accepts: every axis any term mask, trend degree, harmonic counts and
 * reversal rows, any scalars (tests/proofs/any_layout.h), the model's header
 * fields any value within the loader's invariants (below). The term kernel
 * abbe_axis_terms_q runs as its contract (terms_q_contract.h, proven by
 * terms_q_any.c for every layout and the coefficient box; its preconditions
 * are checked here at each call); everything else runs as it is: the
 * assembly, the backlash with the reversal blocks (their rows read from the
 * array), the thermal term, the compensator. */
#include "terms_q_contract.h"
#define PROOF_LAYOUT_COEF_UNION
#include "any_layout.h"

#include "abbe/comp.h"
#include "abbe/error.h"

static abbe_model_t model;
static abbe_comp_t comp;
static int32_t coef[ABBE_AXES][ANY_COEF_WORDS];

static int32_t any_i32(void)
{
    return Frama_C_int_interval(INT32_MIN, INT32_MAX);
}

/* The model's own fields as the loader leaves them (build_model,
 * build_assembly): any features (a superset: the loader also ties REVERSAL
 * to BACKLASH and zeroes the fields of an absent feature), any reference
 * point and tool offset, the squareness within +/-SQUARENESS_CAP = 2^28
 * (check_ranges), its constant lever part -ref_y S_xy + ref_z S_xz and
 * ref_z S_yz within +/-2^60 (|ref| <= 2^31 times |S| <= 2^28, twice) */
static void any_model(abbe_model_t *m)
{
    memset(m, 0, sizeof *m);
    m->features = Frama_C_unsigned_int_interval(0u, ABBE_FEATURE_ALL);
    m->version_major = 1u;
    m->version_minor = (uint16_t)Frama_C_unsigned_int_interval(0u, 1u);
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        m->reference_nm[j] = any_i32();
        m->tool_offset_nm[j] = any_i32();
        m->squareness_q36[j] = Frama_C_int_interval(-(1 << 28), 1 << 28);
        m->ref_half_nm[j] = m->reference_nm[j] >> 1;
        any_axis(&m->axis[j], coef[j]);
    }
    for (unsigned k = 0; k < 2u; k++) {
        m->square_const_q36[k] = Frama_C_long_long_interval(-(1LL << 60), 1LL << 60);
    }
}

int main(void)
{
    any_model(&model);
    /* the evaluation: every position, direction state and temperature */
    abbe_input_q_t in_q;
    abbe_error_q_t out_q;
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        in_q.pos_nm[j] = any_i32();
        in_q.dir_state_q30[j] = any_i32();
        in_q.temp_mdegc[j] = any_i32();
    }
    (void)abbe_error_eval_q(&model, &in_q, &out_q);
    /* the compensator: any configuration, any number of cycles of any input */
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
