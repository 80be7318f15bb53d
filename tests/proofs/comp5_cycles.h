/* The five-axis compensator's any-input part of the Eva harnesses comp_five.c
 * and eval_five_any.c (one copy: docs/proofs.md): any configuration
 * (any5_config) and any number of cycles of abbe_comp_step5_q (PROOF_Q) or
 * abbe_comp_step5_f32 of any input (any5_cycles), each followed or not by
 * abbe_comp_reset and, given a model, by a re-queued swap of it.
 *
 * Inputs per cycle: any int32 linear position, temperature and angle (_q);
 * _f32: every finite linear position and angle and every temperature in
 * [-10^6, 10^6] degC, or with PROOF_NONFINITE every one of them any 32 bits
 * (NaN and the infinities included: analysed with -warn-special-float none);
 * any direction, freshness and fault mask.
 * scripts/prove.sh names any5_cycles in its slevel options. */
#ifndef PROOF_COMP5_CYCLES_H
#define PROOF_COMP5_CYCLES_H

#include "__fc_builtin.h"
#include <string.h>

#include "abbe/comp.h"
#include "abbe/five_axis.h"

#include "any_inputs.h" /* any_i32, any_f32, any_temp */

/* any configuration abbe_comp_init may be given (the refused ones included) */
static void any5_config(abbe_comp_config_t *cfg)
{
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        cfg->warn_nm[j] = any_i32();
        cfg->limit_nm[j] = any_i32();
        cfg->rate_nm_per_cycle[j] = any_i32();
        cfg->axis_sign[j] = (int8_t)Frama_C_interval(INT8_MIN, INT8_MAX);
    }
    cfg->fade_cycles = (uint16_t)Frama_C_interval(0, 65535);
    cfg->stale_cycles = (uint16_t)Frama_C_interval(0, 65535);
}

/* any number of cycles of any input, resets among them, and (reswap not NULL)
 * re-queued swaps of reswap */
static void any5_cycles(abbe_comp_t *comp, const abbe_five_model_t *reswap)
{
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
            in.lin.temp_c[j] = any_temp();
            in.lin.dir[j] = (int8_t)Frama_C_interval(INT8_MIN, INT8_MAX);
        }
        in.angle_deg[0] = any_f32();
        in.angle_deg[1] = any_f32();
#endif
        in.lin.fresh = (uint8_t)Frama_C_interval(0, 255);
        in.lin.axis_fault_mask = (uint8_t)Frama_C_interval(0, 255);
#if defined(PROOF_Q)
        (void)abbe_comp_step5_q(comp, &in, &out);
#else
        (void)abbe_comp_step5_f32(comp, &in, &out);
#endif
        if (Frama_C_nondet(0, 1)) {
            (void)abbe_comp_reset(comp);
        }
        if (reswap != NULL && Frama_C_nondet(0, 1)) {
            (void)abbe_comp_swap_five_model(comp, reswap);
        }
    }
}

#endif
