/* A format 1.0 library (the same sources built with ABBE_NO_REVERSAL, what
 * CMake's ABBE_WITH_REVERSAL=OFF gives): it reads every 1.0 golden table and
 * meets its golden vectors, and refuses every 1.1 table with the minor-version
 * status, before looking at anything else (as the library before format 1.1
 * did). */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "abbe/abbe.h"
#include "golden_data.h"
#include "golden_inputs.h"

static void test_reads_1_0_refuses_1_1(void **state)
{
    (void)state;
    assert_int_equal(ABBE_TABLE_FORMAT_MINOR, 0);
    unsigned n_1_0 = 0, n_1_1 = 0;
    double worst = 0.0;
    for (uint32_t t = 0; t < abbe_golden_table_count; t++) {
        const abbe_golden_table_t *gt = &abbe_golden_tables[t];
        const unsigned minor = gt->blob[6] | (unsigned)gt->blob[7] << 8;
        abbe_model_t m;
        memset(&m, 0x5A, sizeof m);
        abbe_status_t st = abbe_model_load(&m, gt->blob, gt->blob_size);
        if (minor > 0u) {
            assert_int_equal(st, ABBE_E_VERSION_MINOR);
            n_1_1++;
            continue;
        }
        assert_int_equal(st, ABBE_OK);
        n_1_0++;
        for (uint32_t i = gt->first_point; i < gt->first_point + gt->n_points; i++) {
            const abbe_golden_point_t *p = &abbe_golden_points[i];
            abbe_input_f32_t in_f;
            abbe_input_q_t in_q;
            golden_inputs(p, &in_f, &in_q);
            abbe_error_f32_t ef;
            abbe_error_q_t eq;
            assert_int_equal(abbe_error_eval_f32(&m, &in_f, &ef), ABBE_OK);
            assert_int_equal(abbe_error_eval_q(&m, &in_q, &eq), ABBE_OK);
            for (int k = 0; k < 3; k++) {
                double df = fabs((double)ef.error_um[k] * 1e6 - p->expect_f32_pm[k]);
                double dq = fabs((double)eq.error_nm[k] * 1e3 - p->expect_q_pm[k]);
                worst = fmax(worst, fmax(df, dq));
                assert_true(df <= ABBE_GOLDEN_TOL_PM && dq <= ABBE_GOLDEN_TOL_PM);
            }
        }
        /* the reversal of a 1.0 table is its constant backlash */
        for (unsigned j = 0; j < ABBE_AXES; j++) {
            float vf;
            int32_t vq;
            assert_int_equal(abbe_reversal_eval_f32(&m, j, 12.5f, &vf), ABBE_OK);
            assert_int_equal(abbe_reversal_eval_q(&m, j, 12500000, &vq), ABBE_OK);
            assert_true(fabs((double)vf * 1e6 - vq) <= 1.0);
        }
    }
    printf("format 1.0 library: %u tables read (max |err| %.0f pm), %u format 1.1 tables refused\n", n_1_0, worst,
           n_1_1);
    assert_true(n_1_0 >= 4u && n_1_1 >= 2u);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_reads_1_0_refuses_1_1),
    };
    return cmocka_run_group_tests_name("format_1_0", tests, NULL, NULL);
}
