/* Eva harness: the compensator with a five-axis model (comp_five.c,
 * comp_five_q.c with PROOF_Q, else comp_five_f32.c; comp.c's safety layer):
 * on every five-axis table the loader accepts with the layout and
 * coefficients of a golden table of PROOF_TABLES_H (tests/golden/golden_five.c)
 * and any scalar field (PROOF_ANY_SCALARS, any_scalars.h), queued by
 * abbe_comp_swap_five_model; any configuration abbe_comp_init is given (a
 * refused one leaves no compensator); then any number of cycles of
 * abbe_comp_step5_q / _f32 with any linear position, angle, temperature,
 * direction, freshness and fault mask (the float ones: every finite
 * position and angle, every temperature in [-10^6, 10^6] degC), with
 * resets and re-queued swaps of the same model among them (docs/proofs.md). */
#include "__fc_builtin.h"
#include <string.h>

#include "abbe/comp.h"
#include "abbe/five_axis.h"

#include "tables.h"

#if defined(PROOF_ANY_SCALARS)
#define PROOF_FIVE 1
#include "any_scalars.h"
#endif

static abbe_five_model_t model;
static abbe_comp_t comp;

static int32_t any_i32(void)
{
    return Frama_C_int_interval(INT32_MIN, INT32_MAX);
}

#if !defined(PROOF_Q)
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
    any_rotary_scalars((unsigned char *)blob);
#endif
    if (abbe_five_model_load(&model, blob, size) != ABBE_OK) {
        return 1;
    }
    /* any configuration; the compensator starts without a model and gets the
     * five-axis one queued, as a controller does after a load */
    abbe_comp_config_t cfg;
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        cfg.warn_nm[j] = any_i32();
        cfg.limit_nm[j] = any_i32();
        cfg.rate_nm_per_cycle[j] = any_i32();
        cfg.axis_sign[j] = (int8_t)Frama_C_interval(INT8_MIN, INT8_MAX);
    }
    cfg.fade_cycles = (uint16_t)Frama_C_interval(0, 65535);
    cfg.stale_cycles = (uint16_t)Frama_C_interval(0, 65535);
    if (abbe_comp_init(&comp, &cfg, NULL) != ABBE_OK || abbe_comp_enable(&comp) != ABBE_OK) {
        return 1;
    }
    (void)abbe_comp_swap_five_model(&comp, &model);
    while (Frama_C_nondet(0, 1)) {
        abbe_comp_output5_t out;
#if defined(PROOF_Q)
        abbe_comp_input5_q_t in;
        for (unsigned j = 0; j < ABBE_AXES; j++) {
            in.lin.pos_nm[j] = any_i32();
            in.lin.temp_mdegc[j] = any_i32();
            in.lin.dir[j] = (int8_t)Frama_C_interval(INT8_MIN, INT8_MAX);
        }
        in.angle_udeg[0] = any_i32();
        in.angle_udeg[1] = any_i32();
#else
        abbe_comp_input5_f32_t in;
        for (unsigned j = 0; j < ABBE_AXES; j++) {
            in.lin.pos_mm[j] = any_f32();
            in.lin.temp_c[j] = Frama_C_float_interval(-1.0e6f, 1.0e6f);
            in.lin.dir[j] = (int8_t)Frama_C_interval(INT8_MIN, INT8_MAX);
        }
        in.angle_deg[0] = any_f32();
        in.angle_deg[1] = any_f32();
#endif
        in.lin.fresh = (uint8_t)Frama_C_interval(0, 255);
        in.lin.axis_fault_mask = (uint8_t)Frama_C_interval(0, 255);
#if defined(PROOF_Q)
        (void)abbe_comp_step5_q(&comp, &in, &out);
#else
        (void)abbe_comp_step5_f32(&comp, &in, &out);
#endif
        if (Frama_C_nondet(0, 1)) {
            (void)abbe_comp_reset(&comp);
        }
        if (Frama_C_nondet(0, 1)) {
            (void)abbe_comp_swap_five_model(&comp, &model);
        }
    }
    return 0;
}
