/* golden_inputs.h: the f32 and q inputs of one golden point (golden_data.h), for
 * the tests that evaluate the golden vectors (test_eval.c, test_format_1_0.c). */
#ifndef ABBE_TEST_GOLDEN_INPUTS_H
#define ABBE_TEST_GOLDEN_INPUTS_H

#include <string.h>

#include "abbe/abbe.h"
#include "golden_data.h"

static inline void golden_inputs(const abbe_golden_point_t *p, abbe_input_f32_t *in_f,
                                 abbe_input_q_t *in_q)
{
    memcpy(in_f->pos_mm, p->pos_mm, sizeof in_f->pos_mm);
    memcpy(in_f->dir_state, p->dir_state, sizeof in_f->dir_state);
    memcpy(in_f->temp_c, p->temp_c, sizeof in_f->temp_c);
    memcpy(in_q->pos_nm, p->pos_nm, sizeof in_q->pos_nm);
    memcpy(in_q->dir_state_q30, p->dir_q30, sizeof in_q->dir_state_q30);
    memcpy(in_q->temp_mdegc, p->temp_mdegc, sizeof in_q->temp_mdegc);
}

#endif /* ABBE_TEST_GOLDEN_INPUTS_H */
