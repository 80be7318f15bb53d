/* Golden vectors on the target, single-precision variant (Cortex-M4F).
 *
 * Loads every golden table (tests/golden/golden_data.c), evaluates
 * abbe_error_eval_f32 at every golden point and abbe_term_eval_f32 at every
 * golden term position, and compares with the float64 Python reference.
 * The comparison is done in double (a test-side choice: the library itself
 * never uses double) so it adds no rounding of its own.
 * Prints the max abs error per table and overall; exit 0 only if every
 * status, flag and value is within ABBE_GOLDEN_TOL_PM. */
#include <stdint.h>

#include "abbe/abbe.h"
#include "golden_data.h"
#include "semihost.h"

static uint32_t failures;

static void fail(const char *what, uint32_t index, int32_t got, int32_t want)
{
    if (failures < 20u) {
        sh_puts("FAIL ");
        sh_puts(what);
        sh_puts(" #");
        sh_put_u32(index);
        sh_puts(": got ");
        sh_put_i32(got);
        sh_puts(" want ");
        sh_put_i32(want);
        sh_puts("\n");
    }
    failures++;
}

/* |value * 1e6 - expect_pico|, in pico units, rounded to an integer. */
static int64_t err_pico(float value, int32_t expect_pico, int32_t *got_pico)
{
    double got = (double)value * 1e6;
    double d = got - (double)expect_pico;
    *got_pico = (int32_t)(got < 0.0 ? got - 0.5 : got + 0.5);
    if (d < 0.0) {
        d = -d;
    }
    return (int64_t)(d + 0.5);
}

int main(void)
{
    int64_t max_point_pm = 0;
    int64_t max_term_pico = 0;
    uint32_t n_points = 0u;
    uint32_t n_terms = 0u;

    sh_puts("target_golden_f32: ");
    sh_put_u32(abbe_golden_table_count);
    sh_puts(" tables, tolerance ");
    sh_put_i32(ABBE_GOLDEN_TOL_PM);
    sh_puts(" pm\n");

    for (uint32_t t = 0u; t < abbe_golden_table_count; t++) {
        const abbe_golden_table_t *gt = &abbe_golden_tables[t];
        abbe_model_t model;
        int64_t table_max_pm = 0;
        int64_t table_max_term = 0;
        abbe_status_t st = abbe_model_load(&model, gt->blob, gt->blob_size);
        if (st != ABBE_OK) {
            sh_puts("FAIL load '");
            sh_puts(gt->name);
            sh_puts("': ");
            sh_puts(abbe_strerror(st));
            sh_puts("\n");
            failures++;
            continue;
        }
        for (uint32_t i = gt->first_point; i < gt->first_point + gt->n_points; i++) {
            const abbe_golden_point_t *p = &abbe_golden_points[i];
            abbe_input_f32_t in;
            abbe_error_f32_t out;
            for (unsigned j = 0u; j < ABBE_AXES; j++) {
                in.pos_mm[j] = p->pos_mm[j];
                in.dir_state[j] = p->dir_state[j];
                in.temp_c[j] = p->temp_c[j];
            }
            st = abbe_error_eval_f32(&model, &in, &out);
            if (st != ABBE_OK) {
                fail("eval_f32 status, point", i, (int32_t)st, ABBE_OK);
                continue;
            }
            if (out.flags != p->expect_flags) {
                fail("eval_f32 flags, point", i, (int32_t)out.flags, (int32_t)p->expect_flags);
            }
            for (unsigned j = 0u; j < ABBE_AXES; j++) {
                int32_t got;
                int64_t e = err_pico(out.error_um[j], p->expect_f32_pm[j], &got);
                if (e > table_max_pm) {
                    table_max_pm = e;
                }
                if (e > ABBE_GOLDEN_TOL_PM) {
                    fail("eval_f32 pm, point", i, got, p->expect_f32_pm[j]);
                }
            }
            n_points++;
        }
        for (uint32_t i = gt->first_term; i < gt->first_term + gt->n_terms; i++) {
            const abbe_golden_term_t *g = &abbe_golden_terms[i];
            float v = 0.0f;
            int32_t got;
            st = abbe_term_eval_f32(&model, g->axis, g->term, g->pos_mm, &v);
            if (st != ABBE_OK) {
                fail("term_eval_f32 status, term", i, (int32_t)st, ABBE_OK);
                continue;
            }
            int64_t e = err_pico(v, g->expect_f32_pico, &got);
            if (e > table_max_term) {
                table_max_term = e;
            }
            if (e > ABBE_GOLDEN_TOL_PM) {
                fail("term_eval_f32 pico, term", i, got, g->expect_f32_pico);
            }
            n_terms++;
        }
        sh_puts("  table '");
        sh_puts(gt->name);
        sh_puts("': ");
        sh_put_u32(gt->n_points);
        sh_puts(" points max |err| ");
        sh_put_i64(table_max_pm);
        sh_puts(" pm, ");
        sh_put_u32(gt->n_terms);
        sh_puts(" terms max |err| ");
        sh_put_i64(table_max_term);
        sh_puts(" pm|prad\n");
        if (table_max_pm > max_point_pm) {
            max_point_pm = table_max_pm;
        }
        if (table_max_term > max_term_pico) {
            max_term_pico = table_max_term;
        }
    }

    sh_puts("f32: ");
    sh_put_u32(n_points);
    sh_puts(" points, max abs error ");
    sh_put_i64(max_point_pm);
    sh_puts(" pm; ");
    sh_put_u32(n_terms);
    sh_puts(" terms, max abs error ");
    sh_put_i64(max_term_pico);
    sh_puts(" pm|prad; stack used ");
    sh_put_u32(sh_stack_high_water());
    sh_puts(" B; ");
    if (failures != 0u || n_points == 0u) {
        sh_put_u32(failures);
        sh_puts(" FAILURES\n");
        return 1;
    }
    sh_puts("PASS\n");
    return 0;
}
