/* Golden vectors on the target, fixed-point variant (Cortex-M3).
 *
 * Every golden table, point and term through abbe_error_eval_q and
 * abbe_term_eval_q (abbe_reversal_eval_q for the reversal entries), compared with the float64 Python reference in integers
 * only: the image must link without any float or double routine (checked by
 * target_golden_q_no_float). Exit 0 only if every status, flag and value is
 * within ABBE_GOLDEN_TOL_PM. */
#include "golden_harness.h"

static abbe_status_t eval_point(const abbe_model_t *m, const abbe_golden_point_t *p,
                                int64_t got_pm[ABBE_AXES], uint32_t *flags)
{
    abbe_input_q_t in;
    abbe_error_q_t out;
    for (unsigned j = 0u; j < ABBE_AXES; j++) {
        in.pos_nm[j] = p->pos_nm[j];
        in.dir_state_q30[j] = p->dir_q30[j];
        in.temp_mdegc[j] = p->temp_mdegc[j];
    }
    abbe_status_t st = abbe_error_eval_q(m, &in, &out);
    for (unsigned j = 0u; j < ABBE_AXES; j++) {
        got_pm[j] = (int64_t)out.error_nm[j] * 1000;
    }
    *flags = out.flags;
    return st;
}

static abbe_status_t eval_term(const abbe_model_t *m, const abbe_golden_term_t *g, int64_t *got_pico)
{
    int32_t v = 0;
    abbe_status_t st = g->term == ABBE_GOLDEN_TERM_REVERSAL ? abbe_reversal_eval_q(m, g->axis, g->pos_nm, &v)
                                                            : abbe_term_eval_q(m, g->axis, g->term, g->pos_nm, &v);
    *got_pico = v;
    return st;
}

static int32_t expect_point(const abbe_golden_point_t *p, unsigned axis)
{
    return p->expect_q_pm[axis];
}

static int32_t expect_term(const abbe_golden_term_t *g)
{
    return g->expect_q_pico;
}

int main(void)
{
    static const golden_variant_t q = {"q", eval_point, eval_term, expect_point, expect_term};
    return golden_run(&q);
}
