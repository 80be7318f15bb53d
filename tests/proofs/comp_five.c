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

#include "comp5_cycles.h" /* any_i32, any_f32, the compensator's config and cycles */
#include "tables.h"

#if defined(PROOF_ANY_SCALARS)
#define PROOF_FIVE 1
#include "any_scalars.h"
#endif

static abbe_five_model_t model;
static abbe_comp_t comp;

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
    any5_config(&cfg);
    if (abbe_comp_init(&comp, &cfg, NULL) != ABBE_OK || abbe_comp_enable(&comp) != ABBE_OK) {
        return 1;
    }
    (void)abbe_comp_swap_five_model(&comp, &model);
    any5_cycles(&comp, &model);
    return 0;
}
