/* Golden vectors on the target, fixed-point variant (Cortex-M3).
 *
 * Loads every golden table (tests/golden/golden_data.c), evaluates
 * abbe_error_eval_q at every golden point and abbe_term_eval_q at every golden
 * term position, and compares with the float64 Python reference, in integers
 * only: the image must link without any float or double routine (checked by
 * target_golden_q_no_float).
 * Prints the max abs error per table and overall; exit 0 only if every
 * status, flag and value is within ABBE_GOLDEN_TOL_PM. */
#include <stdint.h>

#include "abbe/abbe.h"
#include "golden_data.h"
#include "semihost.h"

static uint32_t failures;

static void fail(const char *what, uint32_t index, int64_t got, int32_t want)
{
    if (failures < 20u) {
        sh_puts("FAIL ");
        sh_puts(what);
        sh_puts(" #");
        sh_put_u32(index);
        sh_puts(": got ");
        sh_put_i64(got);
        sh_puts(" want ");
        sh_put_i32(want);
        sh_puts("\n");
    }
    failures++;
}

static int64_t abs64(int64_t v)
{
    return v < 0 ? -v : v;
}

int main(void)
{
    int64_t max_point_pm = 0;
    int64_t max_term_pico = 0;
    uint32_t n_points = 0u;
    uint32_t n_terms = 0u;

    sh_puts("target_golden_q: ");
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
            abbe_input_q_t in;
            abbe_error_q_t out;
            for (unsigned j = 0u; j < ABBE_AXES; j++) {
                in.pos_nm[j] = p->pos_nm[j];
                in.dir_state_q30[j] = p->dir_q30[j];
                in.temp_mdegc[j] = p->temp_mdegc[j];
            }
            st = abbe_error_eval_q(&model, &in, &out);
            if (st != ABBE_OK) {
                fail("eval_q status, point", i, (int64_t)st, ABBE_OK);
                continue;
            }
            if (out.flags != p->expect_flags) {
                fail("eval_q flags, point", i, (int64_t)out.flags, (int32_t)p->expect_flags);
            }
            for (unsigned j = 0u; j < ABBE_AXES; j++) {
                int64_t got_pm = (int64_t)out.error_nm[j] * 1000;
                int64_t e = abs64(got_pm - p->expect_q_pm[j]);
                if (e > table_max_pm) {
                    table_max_pm = e;
                }
                if (e > ABBE_GOLDEN_TOL_PM) {
                    fail("eval_q pm, point", i, got_pm, p->expect_q_pm[j]);
                }
            }
            n_points++;
        }
        for (uint32_t i = gt->first_term; i < gt->first_term + gt->n_terms; i++) {
            const abbe_golden_term_t *g = &abbe_golden_terms[i];
            int32_t v = 0;
            st = abbe_term_eval_q(&model, g->axis, g->term, g->pos_nm, &v);
            if (st != ABBE_OK) {
                fail("term_eval_q status, term", i, (int64_t)st, ABBE_OK);
                continue;
            }
            int64_t e = abs64((int64_t)v - g->expect_q_pico);
            if (e > table_max_term) {
                table_max_term = e;
            }
            if (e > ABBE_GOLDEN_TOL_PM) {
                fail("term_eval_q pico, term", i, v, g->expect_q_pico);
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

    sh_puts("q: ");
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
