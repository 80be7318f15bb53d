/* Evaluation: the golden vectors of the float64 Python reference for both
 * variants, plus analytic cases built in C (so a sign error shared by the
 * Python reference and the library would still be caught), kernel accuracy
 * and the bad-input paths. */
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
#include "blob_builder.h"
#include "golden_data.h"
#include "golden_inputs.h"
#include "internal.h"

/* ---- golden vectors ------------------------------------------------------ */

static void test_golden_error_both_variants(void **state)
{
    (void)state;
    double worst_f32 = 0.0, worst_q = 0.0;
    for (uint32_t t = 0; t < abbe_golden_table_count; t++) {
        const abbe_golden_table_t *gt = &abbe_golden_tables[t];
        abbe_model_t m;
        assert_int_equal(abbe_model_load(&m, gt->blob, gt->blob_size), ABBE_OK);
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
                if (df > worst_f32) worst_f32 = df;
                if (dq > worst_q) worst_q = dq;
                if (df > ABBE_GOLDEN_TOL_PM || dq > ABBE_GOLDEN_TOL_PM) {
                    fail_msg("table %s point %u axis %d: f32 off by %.0f pm, q off by %.0f pm", gt->name,
                             (unsigned)i, k, df, dq);
                }
            }
            if ((ef.flags ^ p->expect_flags) & ABBE_FLAG_OUT_OF_TRAVEL) {
                fail_msg("table %s point %u: f32 flags %x, expected %x (pos %.9g %.9g %.9g mm)", gt->name,
                         (unsigned)i, ef.flags, p->expect_flags, (double)p->pos_mm[0], (double)p->pos_mm[1],
                         (double)p->pos_mm[2]);
            }
            assert_int_equal(eq.flags & ABBE_FLAG_OUT_OF_TRAVEL, p->expect_flags & ABBE_FLAG_OUT_OF_TRAVEL);
        }
    }
    printf("golden: max |f32 - ref| = %.0f pm, max |q - ref| = %.0f pm (bound %d pm)\n", worst_f32, worst_q,
           ABBE_GOLDEN_TOL_PM);
}

static void test_golden_terms_both_variants(void **state)
{
    (void)state;
    double worst_f32 = 0.0, worst_q = 0.0;
    for (uint32_t t = 0; t < abbe_golden_table_count; t++) {
        const abbe_golden_table_t *gt = &abbe_golden_tables[t];
        abbe_model_t m;
        assert_int_equal(abbe_model_load(&m, gt->blob, gt->blob_size), ABBE_OK);
        for (uint32_t i = gt->first_term; i < gt->first_term + gt->n_terms; i++) {
            const abbe_golden_term_t *g = &abbe_golden_terms[i];
            float vf;
            int32_t vq;
            if (g->term == ABBE_GOLDEN_TERM_REVERSAL) { /* the axis' total reversal, pm */
                assert_int_equal(abbe_reversal_eval_f32(&m, g->axis, g->pos_mm, &vf), ABBE_OK);
                assert_int_equal(abbe_reversal_eval_q(&m, g->axis, g->pos_nm, &vq), ABBE_OK);
            } else {
                assert_int_equal(abbe_term_eval_f32(&m, g->axis, g->term, g->pos_mm, &vf), ABBE_OK);
                assert_int_equal(abbe_term_eval_q(&m, g->axis, g->term, g->pos_nm, &vq), ABBE_OK);
            }
            /* float result in um / urad -> pico */
            double df = fabs((double)vf * 1e6 - g->expect_f32_pico);
            double dq = fabs((double)vq - g->expect_q_pico);
            if (df > worst_f32) worst_f32 = df;
            if (dq > worst_q) worst_q = dq;
            /* 2 nm (linear) or 0.1 urad... no: a term alone must meet 1 nm / 1 nrad */
            if (df > 1000.0 || dq > 1000.0) {
                fail_msg("table %s term %u/%u at %d nm: f32 off by %.0f, q off by %.0f pico", gt->name, g->axis,
                         g->term, g->pos_nm, df, dq);
            }
        }
    }
    printf("golden terms: max |f32 - ref| = %.0f pico, max |q - ref| = %.0f pico\n", worst_f32, worst_q);
}

/* Every set of f32 kernels this build and CPU have (x86-64: SSE2 and, where
 * the CPU has AVX2 and FMA, x86-64-v3; elsewhere one set), each through the
 * golden vectors with the same tolerance, and the sets agree closely. */
static void test_golden_f32_every_kernel_set(void **state)
{
    (void)state;
    double worst_between = 0.0;
    for (uint32_t t = 0; t < abbe_golden_table_count; t++) {
        const abbe_golden_table_t *gt = &abbe_golden_tables[t];
        abbe_model_t m;
        assert_int_equal(abbe_model_load(&m, gt->blob, gt->blob_size), ABBE_OK);
        const uint8_t detected = m.simd;
        for (uint32_t i = gt->first_point; i < gt->first_point + gt->n_points; i++) {
            const abbe_golden_point_t *p = &abbe_golden_points[i];
            abbe_input_f32_t in;
            memcpy(in.pos_mm, p->pos_mm, sizeof in.pos_mm);
            memcpy(in.dir_state, p->dir_state, sizeof in.dir_state);
            memcpy(in.temp_c, p->temp_c, sizeof in.temp_c);
            abbe_error_f32_t e[2];
            for (unsigned k = 0; k <= detected; k++) { /* 0: baseline; 1: x86-64-v3 */
                m.simd = (uint8_t)k;
                assert_int_equal(abbe_error_eval_f32(&m, &in, &e[k]), ABBE_OK);
                assert_int_equal(e[k].flags, p->expect_flags);
                for (int j = 0; j < 3; j++) {
                    double d = fabs((double)e[k].error_um[j] * 1e6 - p->expect_f32_pm[j]);
                    if (d > ABBE_GOLDEN_TOL_PM) {
                        fail_msg("table %s point %u axis %d, kernels %u: off by %.0f pm", gt->name, (unsigned)i, j, k, d);
                    }
                }
            }
            for (int j = 0; detected && j < 3; j++) {
                double d = fabs((double)e[0].error_um[j] - (double)e[1].error_um[j]) * 1e6;
                worst_between = d > worst_between ? d : worst_between;
            }
            m.simd = detected;
        }
    }
    printf("f32 kernel sets: max difference between them %.0f pm\n", worst_between);
    assert_true(worst_between < 500.0);
}

/* ---- analytic cases ------------------------------------------------------ */

static uint8_t blob[8192] __attribute__((aligned(8))); /* tables must be 4-byte aligned */
static int32_t coef_a[64], coef_b[64], coef_c[64];

static void load_table(const tb_table_t *t, abbe_model_t *m)
{
    size_t n = tb_build(t, blob, sizeof blob);
    assert_true(n > 0);
    assert_int_equal(abbe_model_load(m, blob, n), ABBE_OK);
}

static void eval_both(const abbe_model_t *m, double x_mm, double y_mm, double z_mm, double out_um[2][3],
                      uint32_t flags[2])
{
    abbe_input_f32_t in_f;
    abbe_input_q_t in_q;
    memset(&in_f, 0, sizeof in_f);
    memset(&in_q, 0, sizeof in_q);
    double pos[3] = {x_mm, y_mm, z_mm};
    for (int k = 0; k < 3; k++) {
        in_f.pos_mm[k] = (float)pos[k];
        in_q.pos_nm[k] = (int32_t)lround(pos[k] * 1e6);
        in_f.temp_c[k] = 20.0f;
        in_q.temp_mdegc[k] = 20000;
    }
    abbe_error_f32_t ef;
    abbe_error_q_t eq;
    assert_int_equal(abbe_error_eval_f32(m, &in_f, &ef), ABBE_OK);
    assert_int_equal(abbe_error_eval_q(m, &in_q, &eq), ABBE_OK);
    for (int k = 0; k < 3; k++) {
        out_um[0][k] = ef.error_um[k];
        out_um[1][k] = eq.error_nm[k] / 1000.0;
    }
    flags[0] = ef.flags;
    flags[1] = eq.flags;
}

#define NM(mm) ((int32_t)((mm) * 1000000))
#define LIN_Q(um) ((int32_t)lround((um) * 256000.0))          /* um -> 2^-8 nm */
#define ANG_Q(urad) ((int32_t)lround((urad) * 68719.476736)) /* urad -> 2^-36 rad */

/* d_x(x) = c * u, u = (2x - min - max) / span: a linear positioning error.
 * Eq. 3: dX = -d_x(x). Checked at three points and beyond the travel (held). */
static void test_positioning_sign_and_hold(void **state)
{
    (void)state;
    tb_table_t t;
    tb_init(&t);
    t.axis[0].term_mask = 1u << ABBE_TERM_DX;
    t.axis[0].trend_degree = 1;
    coef_a[0] = 0;
    coef_a[1] = LIN_Q(10.0); /* 10 um * u */
    t.axis[0].coef_q = coef_a;
    abbe_model_t m;
    load_table(&t, &m);
    double e[2][3];
    uint32_t f[2];
    const double xs[] = {0.0, 125.0, 500.0};
    const double us[] = {-1.0, -0.5, 1.0};
    for (int i = 0; i < 3; i++) {
        eval_both(&m, xs[i], 0, 0, e, f);
        for (int v = 0; v < 2; v++) {
            assert_true(fabs(e[v][0] - (-10.0 * us[i])) < 0.002);
            assert_true(fabs(e[v][1]) < 1e-9 && fabs(e[v][2]) < 1e-9);
            assert_int_equal(f[v] & ABBE_FLAG_OUT_OF_TRAVEL, 0);
        }
    }
    eval_both(&m, 600.0, 0, 0, e, f); /* beyond max: held at u = 1 */
    for (int v = 0; v < 2; v++) {
        assert_true(fabs(e[v][0] + 10.0) < 0.002);
        assert_int_equal(f[v] & ABBE_FLAG_OUT_OF_TRAVEL, ABBE_FLAG_OUT_OF_TRAVEL);
    }
}

/* Squareness only: dX = y S_xy - z S_xz, dY = -z S_yz, with positions relative
 * to the reference point. */
static void test_squareness_levers(void **state)
{
    (void)state;
    tb_table_t t;
    tb_init(&t);
    t.features = ABBE_FEATURE_SQUARENESS;
    t.reference_nm[0] = NM(100);
    t.reference_nm[1] = NM(-200);
    t.reference_nm[2] = NM(-300);
    t.squareness_q36[0] = ANG_Q(20.0);
    t.squareness_q36[1] = ANG_Q(-15.0);
    t.squareness_q36[2] = ANG_Q(30.0);
    abbe_model_t m;
    load_table(&t, &m);
    double e[2][3];
    uint32_t f[2];
    eval_both(&m, 100.0 + 50.0, -200.0 + 100.0, -300.0 - 40.0, e, f);
    /* y = 100 mm, z = -40 mm: dX = 100*20 - (-40)(-15) = 2000 - 600 nm; dY = -(-40)*30 = 1200 nm */
    for (int v = 0; v < 2; v++) {
        assert_true(fabs(e[v][0] - 1.4) < 0.002);
        assert_true(fabs(e[v][1] - 1.2) < 0.002);
        assert_true(fabs(e[v][2]) < 0.002);
    }
}

/* Angular errors with levers (Eq. 3) and the tool-offset Abbe terms (notes §1):
 * constant eps_xz = a on X, eps_yx = b on Y, eps_zy = c on Z (trend degree 0). */
static void test_angles_and_tool_offset(void **state)
{
    (void)state;
    tb_table_t t;
    tb_init(&t);
    t.features = ABBE_FEATURE_TOOL_OFFSET;
    t.tool_nm[0] = NM(10);
    t.tool_nm[1] = NM(20);
    t.tool_nm[2] = NM(150);
    const double a = 12.0, b = -8.0, c = 5.0; /* urad */
    t.axis[0].term_mask = 1u << ABBE_TERM_EZ;
    t.axis[0].trend_degree = 0;
    coef_a[0] = ANG_Q(a);
    t.axis[0].coef_q = coef_a;
    t.axis[1].term_mask = 1u << ABBE_TERM_EX;
    t.axis[1].trend_degree = 0;
    coef_b[0] = ANG_Q(b);
    t.axis[1].coef_q = coef_b;
    t.axis[2].term_mask = 1u << ABBE_TERM_EY;
    t.axis[2].trend_degree = 0;
    coef_c[0] = ANG_Q(c);
    t.axis[2].coef_q = coef_c;
    abbe_model_t m;
    load_table(&t, &m);
    const double x = 300, y = 250, z = 100; /* mm from the reference point (origin) */
    const double tx = 10, ty = 20, tz = 150;
    /* eps_xz = a, eps_yx = b, eps_zy = c; all others 0 */
    double dx = -y * a + ty * a + tz * c;
    double dy = x * a + z * b + tx * (-a) + tz * b;
    double dz = y * b + tx * (-c) + ty * (-b);
    double e[2][3];
    uint32_t f[2];
    eval_both(&m, x, y, z, e, f);
    for (int v = 0; v < 2; v++) {
        assert_true(fabs(e[v][0] - dx / 1000.0) < 0.002);
        assert_true(fabs(e[v][1] - dy / 1000.0) < 0.002);
        assert_true(fabs(e[v][2] - dz / 1000.0) < 0.002);
    }
}

/* Backlash s*B/2 and thermal alpha*dT*(p - ref) + o*dT on the own positioning term. */
static void test_backlash_and_thermal(void **state)
{
    (void)state;
    tb_table_t t;
    tb_init(&t);
    t.features = ABBE_FEATURE_BACKLASH | ABBE_FEATURE_THERMAL;
    for (int j = 0; j < 3; j++) {
        t.axis[j].takeup_nm = NM(1);
        t.axis[j].tref_mdegc = 20000;
    }
    t.axis[0].backlash_q8 = LIN_Q(8.0);                  /* B = 8 um */
    t.axis[1].expansion_q50 = 13510799;                  /* 12 ppm/K */
    t.axis[1].thermal_offset_q16 = 65536;                /* 1 um/K */
    abbe_model_t m;
    load_table(&t, &m);
    abbe_input_f32_t in_f = {{100.0f, 300.0f, 0.0f}, {1.0f, 0.0f, 0.0f}, {20.0f, 25.0f, 20.0f}};
    abbe_input_q_t in_q = {{NM(100), NM(300), 0}, {ABBE_DIR_Q30_ONE, 0, 0}, {20000, 25000, 20000}};
    abbe_error_f32_t ef;
    abbe_error_q_t eq;
    assert_int_equal(abbe_error_eval_f32(&m, &in_f, &ef), ABBE_OK);
    assert_int_equal(abbe_error_eval_q(&m, &in_q, &eq), ABBE_OK);
    /* dX = -(+1 * 8/2) = -4 um; dY = -(12e-6 * 5 K * 300 mm + 1 um/K * 5 K) = -(18 + 5) um */
    assert_true(fabs(ef.error_um[0] + 4.0f) < 0.002f);
    assert_true(abs(eq.error_nm[0] + 4000) <= 2);
    assert_true(fabs(ef.error_um[1] + 23.0f) < 0.002f);
    assert_true(abs(eq.error_nm[1] + 23000) <= 2);
    /* direction state -1: +4 um; out-of-range states are clamped to [-1, 1] */
    in_f.dir_state[0] = -3.0f;
    in_q.dir_state_q30[0] = -3 * (ABBE_DIR_Q30_ONE / 2);
    assert_int_equal(abbe_error_eval_f32(&m, &in_f, &ef), ABBE_OK);
    assert_int_equal(abbe_error_eval_q(&m, &in_q, &eq), ABBE_OK);
    assert_true(fabs(ef.error_um[0] - 4.0f) < 0.002f);
    assert_true(abs(eq.error_nm[0] - 4000) <= 2);
}

/* Reversal blocks (format 1.1): the own positioning term gets s (B + R(p)) / 2
 * with R(p) = sum_k r_k T_k(u), u the trend's argument at the clamped
 * position. X: B = 8, R = 2 + 6 u - 3 T_2 (total 13 + 6u - 6u^2); Y: no terms,
 * B = 0, R = 4 T_7(u); Z: B = 5, a constant block -2 (total 3). The
 * expectations come from cos/acos here, not from the Python reference. */
static int32_t rev_a[3], rev_b[8], rev_c[1];

static void reversal_tables(tb_table_t *t)
{
    tb_init(t);
    t->features = ABBE_FEATURE_BACKLASH | ABBE_FEATURE_REVERSAL;
    for (int j = 0; j < 3; j++) t->axis[j].takeup_nm = NM(1);
    t->axis[0].backlash_q8 = LIN_Q(8.0);
    rev_a[0] = LIN_Q(2.0);
    rev_a[1] = LIN_Q(6.0);
    rev_a[2] = LIN_Q(-3.0);
    t->axis[0].reversal_rows = 3;
    t->axis[0].reversal_q = rev_a;
    memset(rev_b, 0, sizeof rev_b);
    rev_b[7] = LIN_Q(4.0);
    t->axis[1].reversal_rows = 8;
    t->axis[1].reversal_q = rev_b;
    t->axis[2].backlash_q8 = LIN_Q(5.0);
    rev_c[0] = LIN_Q(-2.0);
    t->axis[2].reversal_rows = 1;
    t->axis[2].reversal_q = rev_c;
}

static double expected_reversal_um(int axis, double p_mm)
{
    double u = (2.0 * fmin(fmax(p_mm, 0.0), 500.0) - 500.0) / 500.0;
    if (axis == 0) return 13.0 + 6.0 * u - 6.0 * u * u;
    if (axis == 1) return 4.0 * cos(7.0 * acos(u));
    return 3.0;
}

static void test_reversal_block(void **state)
{
    (void)state;
    tb_table_t t;
    reversal_tables(&t);
    abbe_model_t m;
    load_table(&t, &m);
    const double xs[] = {0.0, 125.0, 250.0, 333.3, 500.0, 620.0, -50.0};
    const double ss[] = {1.0, -1.0, 0.5, 0.0};
    for (size_t i = 0; i < sizeof xs / sizeof xs[0]; i++) {
        for (size_t k = 0; k < sizeof ss / sizeof ss[0]; k++) {
            const double pos[3] = {xs[i], 500.0 - xs[i] * 0.7, xs[(i + 3) % 7]};
            abbe_input_f32_t in_f;
            abbe_input_q_t in_q;
            for (int j = 0; j < 3; j++) {
                in_f.pos_mm[j] = (float)pos[j];
                in_q.pos_nm[j] = (int32_t)lround(pos[j] * 1e6);
                in_f.dir_state[j] = (float)ss[k];
                in_q.dir_state_q30[j] = (int32_t)lround(ss[k] * ABBE_DIR_Q30_ONE);
                in_f.temp_c[j] = 20.0f;
                in_q.temp_mdegc[j] = 20000;
            }
            abbe_error_f32_t ef;
            abbe_error_q_t eq;
            assert_int_equal(abbe_error_eval_f32(&m, &in_f, &ef), ABBE_OK);
            assert_int_equal(abbe_error_eval_q(&m, &in_q, &eq), ABBE_OK);
            for (int j = 0; j < 3; j++) {
                /* -s R / 2 in dX, dY; +s R / 2 in dZ */
                double want = (j == 2 ? 0.5 : -0.5) * ss[k] * expected_reversal_um(j, pos[j]);
                if (fabs(ef.error_um[j] - want) > 0.002 || fabs(eq.error_nm[j] / 1000.0 - want) > 0.002) {
                    fail_msg("axis %d at %.1f mm, s %.1f: f32 %.4f, q %.4f, want %.4f um", j, pos[j], ss[k],
                             (double)ef.error_um[j], eq.error_nm[j] / 1000.0, want);
                }
            }
        }
    }
    /* the reversal alone */
    for (size_t i = 0; i < sizeof xs / sizeof xs[0]; i++) {
        for (unsigned j = 0; j < 3; j++) {
            float vf;
            int32_t vq;
            assert_int_equal(abbe_reversal_eval_f32(&m, j, (float)xs[i], &vf), ABBE_OK);
            assert_int_equal(abbe_reversal_eval_q(&m, j, (int32_t)lround(xs[i] * 1e6), &vq), ABBE_OK);
            double want = expected_reversal_um((int)j, xs[i]);
            assert_true(fabs(vf - want) < 1e-4);
            assert_true(fabs(vq / 1e6 - want) < 1e-4);
        }
    }
    float v;
    int32_t vq;
    assert_int_equal(abbe_reversal_eval_f32(&m, 3, 0.0f, &v), ABBE_E_ARG);
    assert_int_equal(abbe_reversal_eval_f32(NULL, 0, 0.0f, &v), ABBE_E_ARG);
    assert_int_equal(abbe_reversal_eval_f32(&m, 0, 0.0f, NULL), ABBE_E_ARG);
    assert_int_equal(abbe_reversal_eval_f32(&m, 0, NAN, &v), ABBE_E_INPUT);
    assert_int_equal(abbe_reversal_eval_f32(&m, 0, INFINITY, &v), ABBE_E_INPUT);
    assert_int_equal(abbe_reversal_eval_q(&m, 3, 0, &vq), ABBE_E_ARG);
    assert_int_equal(abbe_reversal_eval_q(NULL, 0, 0, &vq), ABBE_E_ARG);
    assert_int_equal(abbe_reversal_eval_q(&m, 0, 0, NULL), ABBE_E_ARG);
    /* a table without BACKLASH has no reversal */
    tb_init(&t);
    load_table(&t, &m);
    assert_int_equal(abbe_reversal_eval_f32(&m, 1, 10.0f, &v), ABBE_OK);
    assert_int_equal(abbe_reversal_eval_q(&m, 1, NM(10), &vq), ABBE_OK);
    assert_true(v == 0.0f && vq == 0);
}

/* A constant reversal block is the same as a change of backlash_um: bit for
 * bit in fixed point; in float the block's s r_0 / 2 is added beside B's, so
 * within two roundings of the component (the block leaves B's code alone). */
static void test_constant_block_is_backlash(void **state)
{
    (void)state;
    tb_table_t t;
    reversal_tables(&t);
    static uint8_t other[4096] __attribute__((aligned(8)));
    abbe_model_t with_block, without;
    load_table(&t, &with_block);
    memcpy(other, blob, sizeof other);
    assert_int_equal(abbe_model_load(&with_block, other, sizeof other), ABBE_OK);
    t.axis[2].backlash_q8 = LIN_Q(3.0);
    t.axis[2].reversal_rows = 0;
    load_table(&t, &without);
    uint32_t rnd = 7u;
    for (int i = 0; i < 500; i++) {
        abbe_input_q_t in_q;
        abbe_input_f32_t in_f;
        for (int j = 0; j < 3; j++) {
            rnd = rnd * 1664525u + 1013904223u;
            in_q.pos_nm[j] = (int32_t)(rnd % 700000000u) - 100000000;
            rnd = rnd * 1664525u + 1013904223u;
            in_q.dir_state_q30[j] = (int32_t)(rnd % (2u * ABBE_DIR_Q30_ONE + 1u)) - ABBE_DIR_Q30_ONE;
            in_q.temp_mdegc[j] = 20000;
            in_f.pos_mm[j] = (float)in_q.pos_nm[j] * 1e-6f;
            in_f.dir_state[j] = (float)in_q.dir_state_q30[j] / (float)ABBE_DIR_Q30_ONE;
            in_f.temp_c[j] = 20.0f;
        }
        abbe_error_q_t a, b;
        abbe_error_f32_t fa, fb;
        assert_int_equal(abbe_error_eval_q(&with_block, &in_q, &a), ABBE_OK);
        assert_int_equal(abbe_error_eval_q(&without, &in_q, &b), ABBE_OK);
        assert_int_equal(a.error_nm[2], b.error_nm[2]);
        assert_int_equal(abbe_error_eval_f32(&with_block, &in_f, &fa), ABBE_OK);
        assert_int_equal(abbe_error_eval_f32(&without, &in_f, &fb), ABBE_OK);
        assert_true(fabsf(fa.error_um[2] - fb.error_um[2]) <= 2.5e-7f * (1.0f + fabsf(fb.error_um[2])));
    }
}

/* A huge temperature drives the fixed-point strain to its clamp: reported. */
static void test_fixed_saturation_reported(void **state)
{
    (void)state;
    tb_table_t t;
    tb_init(&t);
    t.features = ABBE_FEATURE_THERMAL;
    t.axis[0].expansion_q50 = INT32_MAX;
    t.axis[0].tref_mdegc = 20000;
    abbe_model_t m;
    load_table(&t, &m);
    abbe_input_q_t in_q = {{NM(500), 0, 0}, {0, 0, 0}, {INT32_MAX, 0, 0}};
    abbe_error_q_t eq;
    assert_int_equal(abbe_error_eval_q(&m, &in_q, &eq), ABBE_OK);
    assert_int_equal(eq.flags & ABBE_FLAG_SATURATED, ABBE_FLAG_SATURATED);
    /* clamped strain 2^30 * 2^-36 = 1/64 over 500 mm = 7.8 mm, negated */
    assert_true(abs(eq.error_nm[0] + 7812500) <= 2);
    in_q.temp_mdegc[0] = 25000;
    assert_int_equal(abbe_error_eval_q(&m, &in_q, &eq), ABBE_OK);
    assert_int_equal(eq.flags & ABBE_FLAG_SATURATED, 0);
}

static void test_bad_inputs(void **state)
{
    (void)state;
    tb_table_t t;
    tb_init(&t);
    t.features = ABBE_FEATURE_THERMAL;
    abbe_model_t m;
    load_table(&t, &m);
    abbe_input_f32_t in_f = {{1.0f, 2.0f, 3.0f}, {0, 0, 0}, {20, 20, 20}};
    abbe_error_f32_t ef;
    abbe_input_q_t in_q;
    memset(&in_q, 0, sizeof in_q);
    abbe_error_q_t eq;
    float v;
    int32_t vq;
    assert_int_equal(abbe_error_eval_f32(NULL, &in_f, &ef), ABBE_E_ARG);
    assert_int_equal(abbe_error_eval_f32(&m, NULL, &ef), ABBE_E_ARG);
    assert_int_equal(abbe_error_eval_f32(&m, &in_f, NULL), ABBE_E_ARG);
    assert_int_equal(abbe_error_eval_q(NULL, &in_q, &eq), ABBE_E_ARG);
    assert_int_equal(abbe_error_eval_q(&m, NULL, &eq), ABBE_E_ARG);
    assert_int_equal(abbe_error_eval_q(&m, &in_q, NULL), ABBE_E_ARG);
    assert_int_equal(abbe_term_eval_f32(&m, 3, 0, 0.0f, &v), ABBE_E_ARG);
    assert_int_equal(abbe_term_eval_f32(&m, 0, 6, 0.0f, &v), ABBE_E_ARG);
    assert_int_equal(abbe_term_eval_q(&m, 0, 6, 0, &vq), ABBE_E_ARG);
    assert_int_equal(abbe_term_eval_f32(&m, 0, 0, NAN, &v), ABBE_E_INPUT);

    in_f.pos_mm[1] = NAN;
    assert_int_equal(abbe_error_eval_f32(&m, &in_f, &ef), ABBE_E_INPUT);
    assert_true(ef.error_um[0] == 0.0f && ef.error_um[1] == 0.0f);
    in_f.pos_mm[1] = INFINITY;
    assert_int_equal(abbe_error_eval_f32(&m, &in_f, &ef), ABBE_E_INPUT);
    in_f.pos_mm[1] = 2.0f;
    in_f.temp_c[2] = NAN; /* used: the table has thermal terms */
    assert_int_equal(abbe_error_eval_f32(&m, &in_f, &ef), ABBE_E_INPUT);
    /* a finite but absurd temperature: refused like NaN (it made alpha * dT
     * infinite with ABBE_OK, found by the Eva proof of the f32 evaluator) */
    in_f.temp_c[2] = -3e38f;
    assert_int_equal(abbe_error_eval_f32(&m, &in_f, &ef), ABBE_E_INPUT);
    assert_true(ef.error_um[2] == 0.0f);
    in_f.temp_c[2] = 1.0000001e6f;
    assert_int_equal(abbe_error_eval_f32(&m, &in_f, &ef), ABBE_E_INPUT);
    in_f.temp_c[2] = 1.0e6f; /* the last accepted */
    assert_int_equal(abbe_error_eval_f32(&m, &in_f, &ef), ABBE_OK);
    assert_true(isfinite(ef.error_um[0]) && isfinite(ef.error_um[1]) && isfinite(ef.error_um[2]));
    in_f.temp_c[2] = 20.0f;
    in_f.dir_state[0] = NAN; /* ignored: no backlash in this table */
    assert_int_equal(abbe_error_eval_f32(&m, &in_f, &ef), ABBE_OK);
    /* beyond +/-2147 mm: clamped and flagged, not undefined */
    in_f.pos_mm[0] = 1e9f;
    assert_int_equal(abbe_error_eval_f32(&m, &in_f, &ef), ABBE_OK);
    assert_int_equal(ef.flags & ABBE_FLAG_OUT_OF_TRAVEL, ABBE_FLAG_OUT_OF_TRAVEL);
}

/* ---- kernels (white box) -------------------------------------------------- */

static void test_sincos_accuracy(void **state)
{
    (void)state;
    double worst_q = 0.0, worst_f = 0.0;
    uint32_t phase = 12345u;
    for (int i = 0; i < 200000; i++) {
        phase = phase * 1664525u + 1013904223u;
        uint32_t p = (i < 16) ? (uint32_t)i << 28 : phase; /* multiples of 1/16 turn, then random */
        double th = 6.283185307179586 * (double)p / 4294967296.0;
        int32_t sq, cq;
        float sf, cf;
        abbe_sincos_q30(p, &sq, &cq);
        abbe_sincos_f32(p, &sf, &cf);
        double eq = fmax(fabs(sq / 1073741824.0 - sin(th)), fabs(cq / 1073741824.0 - cos(th)));
        double ef = fmax(fabs(sf - sin(th)), fabs(cf - cos(th)));
        if (eq > worst_q) worst_q = eq;
        if (ef > worst_f) worst_f = ef;
    }
    printf("sincos: max error q30 %.3g, f32 %.3g\n", worst_q, worst_f);
    assert_true(worst_q < 4e-9);
    assert_true(worst_f < 2e-7);
}

/* Offset of the clamped position from travel_min (the one argument
 * reduction per axis), as the evaluation computes it: clamped and flagged. */
static uint32_t offset_of(const abbe_axis_model_t *ax, int32_t pos_nm, uint32_t *flags)
{
    return abbe_arg_offset(ax, pos_nm, flags);
}

static void test_offset_clamps_and_flags(void **state)
{
    (void)state;
    tb_table_t t;
    tb_init(&t);
    t.axis[0].travel_min_nm = INT32_MIN; /* the widest travel: span 2^32 - 1 */
    t.axis[0].travel_max_nm = INT32_MAX;
    t.axis[1].travel_min_nm = NM(-400);
    t.axis[1].travel_max_nm = NM(100);
    abbe_model_t m;
    load_table(&t, &m);
    uint32_t f = 0;
    assert_int_equal(offset_of(&m.axis[0], INT32_MIN, &f), 0u);
    assert_int_equal(offset_of(&m.axis[0], INT32_MAX, &f), UINT32_MAX);
    assert_int_equal(offset_of(&m.axis[0], 0, &f), 2147483648u);
    assert_int_equal(f, 0u);
    assert_int_equal(offset_of(&m.axis[1], NM(-400), &f), 0u);
    assert_int_equal(offset_of(&m.axis[1], NM(100), &f), (uint32_t)NM(500));
    assert_int_equal(f, 0u);
    assert_int_equal(offset_of(&m.axis[1], NM(-400) - 1, &f), 0u);
    assert_int_equal(f, ABBE_FLAG_OUT_OF_TRAVEL);
    f = 0;
    assert_int_equal(offset_of(&m.axis[1], INT32_MAX, &f), (uint32_t)NM(500));
    assert_int_equal(f, ABBE_FLAG_OUT_OF_TRAVEL);
    f = 0;
    assert_int_equal(offset_of(&m.axis[1], INT32_MIN, &f), 0u);
    assert_int_equal(f, ABBE_FLAG_OUT_OF_TRAVEL);
}

/* The phase of a 5 mm period 2 m from its origin stays exact to ~1 LSB. */
static void test_phase_far_from_origin(void **state)
{
    (void)state;
    tb_table_t t;
    tb_init(&t);
    t.axis[0].travel_min_nm = NM(-2100);
    t.axis[0].travel_max_nm = NM(2100);
    t.axis[0].harmonics[1] = 1;
    t.axis[0].period_nm[1] = 4999999; /* not a power of two, not a round number */
    t.axis[0].origin_nm[1] = NM(-2000);
    abbe_model_t m;
    load_table(&t, &m);
    const int32_t ps[] = {NM(-2100), NM(-2000), NM(-1999) + 3, 0, NM(2000) - 17, NM(2100)};
    for (size_t i = 0; i < sizeof ps / sizeof ps[0]; i++) {
        uint32_t f = 0;
        uint32_t ph = abbe_arg_phase_q32(&m.axis[0], 1, offset_of(&m.axis[0], ps[i], &f));
        long double turns = ((long double)ps[i] - (long double)NM(-2000)) / 4999999.0L;
        long double frac = turns - floorl(turns);
        long double got = (long double)ph / 4294967296.0L;
        long double d = fabsl(got - frac);
        if (d > 0.5L) d = 1.0L - d;
        assert_true(d < 3.0L / 4294967296.0L);
    }
}

static void test_chebyshev_argument(void **state)
{
    (void)state;
    tb_table_t t;
    tb_init(&t);
    t.axis[1].travel_min_nm = NM(-400);
    t.axis[1].travel_max_nm = 0;
    abbe_model_t m;
    load_table(&t, &m);
    uint32_t f = 0;
    assert_int_equal(abbe_arg_cheb_q30(&m.axis[1], offset_of(&m.axis[1], NM(-400), &f)), -ABBE_Q30_ONE);
    assert_int_equal(abbe_arg_cheb_q30(&m.axis[1], offset_of(&m.axis[1], 0, &f)), ABBE_Q30_ONE);
    assert_int_equal(abbe_arg_cheb_q30(&m.axis[1], offset_of(&m.axis[1], NM(-200), &f)), 0);
    int32_t u = abbe_arg_cheb_q30(&m.axis[1], offset_of(&m.axis[1], NM(-100), &f));
    assert_true(abs(u - ABBE_Q30_ONE / 2) <= 1);
}

/* u_q30 = 2^30 (2d / span - 1) to within 1 LSB (exact to rounding for a power-of-two span),
 * for spans from 1 nm to 2^32 - 1 nm, over the whole travel. */
static void test_chebyshev_argument_any_span(void **state)
{
    (void)state;
    static const uint32_t spans[] = {1u, 2u, 3u, 1000u, 65536u, 999999937u, 1073741824u, 1073741825u,
                                     2147483648u, 3000000000u, 4294967295u};
    uint32_t rnd = 99991u;
    long double worst = 0.0L, worst_pow2 = 0.0L;
    for (size_t i = 0; i < sizeof spans / sizeof spans[0]; i++) {
        tb_table_t t;
        tb_init(&t);
        t.axis[2].travel_min_nm = INT32_MIN;
        t.axis[2].travel_max_nm = (int32_t)((int64_t)INT32_MIN + spans[i]);
        abbe_model_t m;
        load_table(&t, &m);
        const uint32_t span = spans[i];
        const int pow2 = (span & (span - 1u)) == 0u;
        for (int k = 0; k < 4000; k++) {
            rnd = rnd * 1664525u + 1013904223u;
            uint32_t d = k == 0 ? 0u : (k == 1 ? span : (uint32_t)((uint64_t)rnd * ((uint64_t)span + 1u) >> 32));
            int32_t u = abbe_arg_cheb_q30(&m.axis[2], d);
            long double exact = (2.0L * d / span - 1.0L) * 1073741824.0L;
            long double e = fabsl((long double)u - exact);
            if (pow2) {
                worst_pow2 = e > worst_pow2 ? e : worst_pow2;
            } else {
                worst = e > worst ? e : worst;
            }
        }
    }
    printf("chebyshev argument: max error %.3Lf LSB, %.3Lf LSB for power-of-two spans\n", worst, worst_pow2);
    assert_true(worst <= 1.0L);
    assert_true(worst_pow2 <= 0.5L);
}

/* The batch calls give exactly the single-point results, and a bad point
 * neither stops the batch nor changes the other points. */
static void test_batch_matches_single_points(void **state)
{
    (void)state;
    enum { N = 64 };
    abbe_input_f32_t in_f[N];
    abbe_input_q_t in_q[N];
    abbe_error_f32_t out_f[N], one_f;
    abbe_error_q_t out_q[N], one_q;
    for (uint32_t t = 0; t < abbe_golden_table_count; t++) {
        const abbe_golden_table_t *gt = &abbe_golden_tables[t];
        abbe_model_t m;
        assert_int_equal(abbe_model_load(&m, gt->blob, gt->blob_size), ABBE_OK);
        for (unsigned i = 0; i < N; i++) {
            const abbe_golden_point_t *p = &abbe_golden_points[gt->first_point + i % gt->n_points];
            memcpy(in_f[i].pos_mm, p->pos_mm, sizeof in_f[i].pos_mm);
            memcpy(in_f[i].dir_state, p->dir_state, sizeof in_f[i].dir_state);
            memcpy(in_f[i].temp_c, p->temp_c, sizeof in_f[i].temp_c);
            memcpy(in_q[i].pos_nm, p->pos_nm, sizeof in_q[i].pos_nm);
            memcpy(in_q[i].dir_state_q30, p->dir_q30, sizeof in_q[i].dir_state_q30);
            memcpy(in_q[i].temp_mdegc, p->temp_mdegc, sizeof in_q[i].temp_mdegc);
        }
        in_f[5].pos_mm[2] = NAN;
        in_f[17].pos_mm[0] = -INFINITY;
        memset(out_f, 0x5A, sizeof out_f);
        assert_int_equal(abbe_error_eval_batch_f32(&m, N, in_f, out_f), ABBE_E_INPUT);
        assert_int_equal(abbe_error_eval_batch_q(&m, N, in_q, out_q), ABBE_OK);
        for (unsigned i = 0; i < N; i++) {
            abbe_status_t st = abbe_error_eval_f32(&m, &in_f[i], &one_f);
            assert_int_equal(st, (i == 5 || i == 17) ? ABBE_E_INPUT : ABBE_OK);
            if (st == ABBE_OK) {
                assert_memory_equal(&out_f[i], &one_f, sizeof one_f);
            } else {
                assert_true(out_f[i].error_um[0] == 0.0f && out_f[i].error_um[1] == 0.0f &&
                            out_f[i].error_um[2] == 0.0f);
                assert_int_equal(out_f[i].flags, ABBE_FLAG_INPUT_INVALID);
            }
            assert_int_equal(abbe_error_eval_q(&m, &in_q[i], &one_q), ABBE_OK);
            assert_memory_equal(&out_q[i], &one_q, sizeof one_q);
        }
        in_f[5].pos_mm[2] = 0.0f;
        in_f[17].pos_mm[0] = 0.0f;
        assert_int_equal(abbe_error_eval_batch_f32(&m, N, in_f, out_f), ABBE_OK);
    }
    abbe_model_t m;
    assert_int_equal(abbe_model_load(&m, abbe_golden_tables[0].blob, abbe_golden_tables[0].blob_size), ABBE_OK);
    assert_int_equal(abbe_error_eval_batch_f32(&m, 0, NULL, NULL), ABBE_OK);
    assert_int_equal(abbe_error_eval_batch_q(&m, 0, NULL, NULL), ABBE_OK);
    assert_int_equal(abbe_error_eval_batch_f32(NULL, 1, in_f, out_f), ABBE_E_ARG);
    assert_int_equal(abbe_error_eval_batch_f32(&m, 1, NULL, out_f), ABBE_E_ARG);
    assert_int_equal(abbe_error_eval_batch_f32(&m, 1, in_f, NULL), ABBE_E_ARG);
    assert_int_equal(abbe_error_eval_batch_q(NULL, 1, in_q, out_q), ABBE_E_ARG);
    assert_int_equal(abbe_error_eval_batch_q(&m, 1, NULL, out_q), ABBE_E_ARG);
    assert_int_equal(abbe_error_eval_batch_q(&m, 1, in_q, NULL), ABBE_E_ARG);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_golden_error_both_variants),
        cmocka_unit_test(test_golden_terms_both_variants),
        cmocka_unit_test(test_golden_f32_every_kernel_set),
        cmocka_unit_test(test_positioning_sign_and_hold),
        cmocka_unit_test(test_squareness_levers),
        cmocka_unit_test(test_angles_and_tool_offset),
        cmocka_unit_test(test_backlash_and_thermal),
        cmocka_unit_test(test_reversal_block),
        cmocka_unit_test(test_constant_block_is_backlash),
        cmocka_unit_test(test_fixed_saturation_reported),
        cmocka_unit_test(test_bad_inputs),
        cmocka_unit_test(test_sincos_accuracy),
        cmocka_unit_test(test_offset_clamps_and_flags),
        cmocka_unit_test(test_phase_far_from_origin),
        cmocka_unit_test(test_chebyshev_argument),
        cmocka_unit_test(test_chebyshev_argument_any_span),
        cmocka_unit_test(test_batch_matches_single_points),
    };
    return cmocka_run_group_tests_name("eval", tests, NULL, NULL);
}
