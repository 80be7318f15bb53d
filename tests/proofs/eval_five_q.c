/* Eva harness: the five-axis fixed-point evaluation (abbe_five_error_eval_q)
 * on a five-axis table the loader accepted (PROOF_TABLE, a golden table of
 * tests/golden/golden_five.c, as in eval_q.c) at every joint position:
 * every int32 linear position, angle (micro-degrees), direction state and
 * temperature (docs/proofs.md). */
#include "__fc_builtin.h"
#include <string.h>

#include "abbe/five_axis.h"

#define PROOF_STR2(x) #x
#define PROOF_STR(x) PROOF_STR2(x)
#include PROOF_STR(PROOF_TABLE)

static uint32_t blob[(sizeof table_bin + 3u) / 4u];
static abbe_five_model_t model;

static int32_t any_i32(void)
{
    return Frama_C_int_interval(INT32_MIN, INT32_MAX);
}

int main(void)
{
    memcpy(blob, table_bin, sizeof table_bin);
    if (abbe_five_model_load(&model, blob, sizeof table_bin) != ABBE_OK) {
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
