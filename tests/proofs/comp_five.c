/* Eva harness: the compensator with a five-axis model (comp_five.c,
 * comp_five_q.c with PROOF_Q, else comp_five_f32.c; comp.c's safety layer):
 * on every five-axis table the loader accepts with the layout and
 * coefficients of a golden table of PROOF_TABLES_H (tests/golden/golden_five.c)
 * and any scalar field (PROOF_ANY_SCALARS, any_scalars.h): any configuration
 * abbe_comp_init is given (a refused one leaves no compensator); the table's
 * bytes loaded into a slot by abbe_comp_load_five_model and queued; a table
 * of unknown bytes of every length 0..PROOF_LOAD_MAX loaded into the queued
 * slot (refused) and into the other one; then any number of cycles of
 * abbe_comp_step5_q / _f32 (the first swaps the queued model in) with any
 * linear position, angle, temperature, direction, freshness and fault mask
 * (the float ones: every finite position and angle, every temperature in
 * [-10^6, 10^6] degC; with PROOF_NONFINITE any 32 bits), with resets and
 * re-queued swaps among them (comp5_cycles.h; docs/proofs.md). */
#include "__fc_builtin.h"
#include <string.h>

#include "abbe/comp.h"
#include "abbe/five_axis.h"

#include "comp5_cycles.h" /* any_i32, any_f32, the compensator's config and cycles */
#include "tables.h"

#if defined(PROOF_ANY_SCALARS)
#define PROOF_FIVE 1
#include "any_scalars.h"
#endif

#ifndef PROOF_LOAD_MAX
#define PROOF_LOAD_MAX 64 /* bytes: the bound of the table of unknown bytes (prove.sh sets it) */
#endif

/* the controller's two model slots: the running one and the one loaded next */
static abbe_five_model_t slot[2];
static abbe_comp_t comp;
static uint32_t any_bytes[PROOF_LOAD_MAX / 4u];

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
    /* any configuration; the compensator starts without a model */
    abbe_comp_config_t cfg;
    any5_config(&cfg);
    if (abbe_comp_init(&comp, &cfg, NULL) != ABBE_OK || abbe_comp_enable(&comp) != ABBE_OK) {
        return 1;
    }
    /* the table's bytes loaded into a slot and queued, as a controller does: the
     * next cycle swaps it in */
    if (abbe_comp_load_five_model(&comp, &slot[0], blob, size) != ABBE_OK) {
        return 1;
    }
    /* then, that model queued, a table of unknown bytes of every length
     * 0..PROOF_LOAD_MAX (each length its own partition; the table ends where the
     * buffer does, as load5.c): into the queued slot it is refused, into the
     * other one the loader runs */
    uint8_t *arr = (uint8_t *)any_bytes;
    Frama_C_make_unknown((char *)arr, PROOF_LOAD_MAX);
    size_t n = Frama_C_interval(0, PROOF_LOAD_MAX);
    //@ split n;
    const uint8_t *bytes = arr + (PROOF_LOAD_MAX - n);
    abbe_status_t st = abbe_comp_load_five_model(&comp, &slot[0], bytes, n);
    //@ assert queued_slot_refused: st == ABBE_E_ARG;
    st = abbe_comp_load_five_model(&comp, &slot[1], bytes, n);
    if (st == ABBE_OK) {
        /* queued instead: a table of any layout, whose cycles are eval_five_any's
         * (within its coefficient box; docs/proofs.md, "Not proven yet") */
        return 0;
    }
    /* merged after the test: an accepted table's state (slot[1] queued) is not
     * joined with a refused one's */
    //@ merge n;
    /* refused: the table's model stays queued; any number of cycles (the first
     * swaps it in), resets and re-queued swaps of it */
    any5_cycles(&comp, &slot[0]);
    return 0;
}
