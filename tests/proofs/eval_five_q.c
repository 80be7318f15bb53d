/* Eva harness: the five-axis fixed-point evaluation (abbe_five_error_eval_q)
 * on every five-axis table the loader accepts with the layout and
 * coefficients of one of the golden tables of PROOF_TABLES_H (from
 * tests/golden/golden_five.c, as in eval_q.c), with PROOF_ANY_SCALARS any
 * scalar field of the linear axes and of the rotary section (any_scalars.h),
 * at every joint position:
 * every int32 linear position, angle (micro-degrees), direction state and
 * temperature (docs/proofs.md). */
#include "__fc_builtin.h"
#include <string.h>

#include "abbe/five_axis.h"

#include "tables.h"

#if defined(PROOF_ANY_SCALARS)
#define PROOF_FIVE 1
#include "any_scalars.h"
#endif

static abbe_five_model_t model;

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
    any_rotary_scalars((unsigned char *)blob);
#endif
    if (abbe_five_model_load(&model, blob, size) != ABBE_OK) {
        return 1;
    }
    abbe_five_input_q_t in;
    abbe_five_error_q_t out;
    for (unsigned j = 0; j < 3u; j++) {
        in.pos_nm[j] = any_i32();
        in.dir_state_q30[j] = any_i32();
        in.temp_mdegc[j] = any_i32();
    }
    in.angle_udeg[0] = any_i32();
    in.angle_udeg[1] = any_i32();
    (void)abbe_five_error_eval_q(&model, &in, &out);
    return 0;
}
