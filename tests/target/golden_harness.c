#include "golden_harness.h"

#include "semihost.h"

static uint32_t failures;

static void fail(const char *variant, const char *what, uint32_t index, int64_t got, int32_t want)
{
    if (failures < 20u) {
        sh_puts("FAIL ");
        sh_puts(variant);
        sh_puts(" ");
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

int golden_run(const golden_variant_t *v)
{
    int64_t max_point_pm = 0, max_term_pico = 0;
    uint32_t n_points = 0u, n_terms = 0u;

    sh_puts("target_golden_");
    sh_puts(v->name);
    sh_puts(": ");
    sh_put_u32(abbe_golden_table_count);
    sh_puts(" tables, tolerance ");
    sh_put_i32(ABBE_GOLDEN_TOL_PM);
    sh_puts(" pm\n");

    for (uint32_t t = 0u; t < abbe_golden_table_count; t++) {
        const abbe_golden_table_t *gt = &abbe_golden_tables[t];
        abbe_model_t model;
        int64_t table_max_pm = 0, table_max_term = 0;
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
            int64_t got[ABBE_AXES];
            uint32_t flags = 0u;
            st = v->eval_point(&model, p, got, &flags);
            if (st != ABBE_OK) {
                fail(v->name, "eval status, point", i, (int64_t)st, ABBE_OK);
                continue;
            }
            if (flags != p->expect_flags) {
                fail(v->name, "eval flags, point", i, (int64_t)flags, (int32_t)p->expect_flags);
            }
            for (unsigned j = 0u; j < ABBE_AXES; j++) {
                int32_t want = v->expect_point(p, j);
                int64_t e = abs64(got[j] - want);
                if (e > table_max_pm) {
                    table_max_pm = e;
                }
                if (e > ABBE_GOLDEN_TOL_PM) {
                    fail(v->name, "eval pm, point", i, got[j], want);
                }
            }
            n_points++;
        }
        for (uint32_t i = gt->first_term; i < gt->first_term + gt->n_terms; i++) {
            const abbe_golden_term_t *g = &abbe_golden_terms[i];
            int64_t got = 0;
            st = v->eval_term(&model, g, &got);
            if (st != ABBE_OK) {
                fail(v->name, "term status, term", i, (int64_t)st, ABBE_OK);
                continue;
            }
            int32_t want = v->expect_term(g);
            int64_t e = abs64(got - want);
            if (e > table_max_term) {
                table_max_term = e;
            }
            if (e > ABBE_GOLDEN_TOL_PM) {
                fail(v->name, "term pico, term", i, got, want);
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

    sh_puts(v->name);
    sh_puts(": ");
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
