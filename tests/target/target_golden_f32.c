/* Golden vectors on the target, single-precision variant (Cortex-M4F).
 *
 * Every golden table, point and term through abbe_error_eval_f32 and
 * abbe_term_eval_f32 (abbe_reversal_eval_f32 for the reversal entries), compared with the float64 Python reference. The
 * conversion of the float result to integer pico units is done in double (a
 * test-side choice: the library never uses double) so it adds no rounding of
 * its own. Exit 0 only if every status, flag and value is within
 * ABBE_GOLDEN_TOL_PM. */
#include "golden_harness.h"

/* float um or urad -> integer pm or prad, rounded */
static int64_t to_pico(float value)
{
    double got = (double)value * 1e6;
    return (int64_t)(got < 0.0 ? got - 0.5 : got + 0.5);
}

static abbe_status_t eval_point(const abbe_model_t *m, const abbe_golden_point_t *p,
                                int64_t got_pm[ABBE_AXES], uint32_t *flags)
{
    abbe_input_f32_t in;
    abbe_error_f32_t out;
    for (unsigned j = 0u; j < ABBE_AXES; j++) {
        in.pos_mm[j] = p->pos_mm[j];
        in.dir_state[j] = p->dir_state[j];
        in.temp_c[j] = p->temp_c[j];
    }
    abbe_status_t st = abbe_error_eval_f32(m, &in, &out);
    for (unsigned j = 0u; j < ABBE_AXES; j++) {
        got_pm[j] = to_pico(out.error_um[j]);
    }
    *flags = out.flags;
    return st;
}

static abbe_status_t eval_term(const abbe_model_t *m, const abbe_golden_term_t *g, int64_t *got_pico)
{
    float v = 0.0f;
    abbe_status_t st = g->term == ABBE_GOLDEN_TERM_REVERSAL ? abbe_reversal_eval_f32(m, g->axis, g->pos_mm, &v)
                                                            : abbe_term_eval_f32(m, g->axis, g->term, g->pos_mm, &v);
    *got_pico = to_pico(v);
    return st;
}

static int32_t expect_point(const abbe_golden_point_t *p, unsigned axis)
{
    return p->expect_f32_pm[axis];
}

static int32_t expect_term(const abbe_golden_term_t *g)
{
    return g->expect_f32_pico;
}

int main(void)
{
    static const golden_variant_t f32 = {"f32", eval_point, eval_term, expect_point, expect_term};
    return golden_run(&f32);
}
