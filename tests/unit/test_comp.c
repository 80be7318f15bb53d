/* Compensator: fades, rate limit, limits, watchdog, axis faults, model swap,
 * backlash direction tracking. The invariant checked throughout: the output
 * never changes by more than the rate limit in one cycle. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "abbe/abbe.h"
#include "blob_builder.h"

#define NM(mm) ((int32_t)((mm) * 1000000))
#define LIN_Q(um) ((int32_t)lround((um) * 256000.0))

static uint8_t blob_a[4096] __attribute__((aligned(8))), blob_b[4096] __attribute__((aligned(8))),
    blob_bad[4096] __attribute__((aligned(8)));
static size_t size_a, size_b;
static int32_t coef_a[2], coef_b[2];

/* Table A: constant d_x(x) = +20 um on X (so dX = -20 um, correction +20 um),
 * backlash B = 10 um on X with 1 mm take-up. Table B: d_x(x) = -30 um. */
static void build_tables(void)
{
    tb_table_t t;
    tb_init(&t);
    t.features = ABBE_FEATURE_BACKLASH;
    for (int j = 0; j < 3; j++) t.axis[j].takeup_nm = NM(1);
    t.axis[0].backlash_q8 = LIN_Q(10.0);
    t.axis[0].term_mask = 1u << ABBE_TERM_DX;
    t.axis[0].trend_degree = 0;
    coef_a[0] = LIN_Q(20.0);
    t.axis[0].coef_q = coef_a;
    size_a = tb_build(&t, blob_a, sizeof blob_a);
    coef_b[0] = LIN_Q(-30.0);
    t.axis[0].coef_q = coef_b;
    size_b = tb_build(&t, blob_b, sizeof blob_b);
    assert_true(size_a > 0 && size_b > 0);
}

static abbe_comp_config_t config(void)
{
    abbe_comp_config_t c;
    memset(&c, 0, sizeof c);
    for (int j = 0; j < 3; j++) {
        c.warn_nm[j] = 50000;
        c.limit_nm[j] = 100000;
        c.rate_nm_per_cycle[j] = 1000;
        c.axis_sign[j] = 1;
    }
    c.fade_cycles = 10;
    c.stale_cycles = 3;
    return c;
}

typedef struct {
    abbe_model_t a, b, spare;
    abbe_comp_t comp;
    abbe_comp_output_t out;
    int32_t last_corr[3];
    int32_t max_step;
} fixture_t;

static fixture_t fx;

static int setup(void **state)
{
    (void)state;
    memset(&fx, 0, sizeof fx);
    build_tables();
    assert_int_equal(abbe_model_load(&fx.a, blob_a, size_a), ABBE_OK);
    assert_int_equal(abbe_model_load(&fx.b, blob_b, size_b), ABBE_OK);
    abbe_comp_config_t c = config();
    assert_int_equal(abbe_comp_init(&fx.comp, &c, &fx.a), ABBE_OK);
    return 0;
}

/* One q step at x (mm), moving in dir along X; records the largest jump. */
static uint32_t step(double x_mm, int8_t dir, int fresh, uint8_t fault_mask)
{
    abbe_comp_input_q_t in;
    memset(&in, 0, sizeof in);
    in.pos_nm[0] = (int32_t)lround(x_mm * 1e6);
    in.dir[0] = dir;
    in.fresh = (uint8_t)fresh;
    in.axis_fault_mask = fault_mask;
    assert_int_equal(abbe_comp_step_q(&fx.comp, &in, &fx.out), ABBE_OK);
    for (int j = 0; j < 3; j++) {
        int32_t d = abs(fx.out.corr_nm[j] - fx.last_corr[j]);
        if (d > fx.max_step) fx.max_step = d;
        fx.last_corr[j] = fx.out.corr_nm[j];
    }
    return fx.out.flags;
}

static void test_config_checked(void **state)
{
    (void)state;
    abbe_comp_t c;
    abbe_comp_config_t cfg = config();
    assert_int_equal(abbe_comp_init(NULL, &cfg, NULL), ABBE_E_ARG);
    assert_int_equal(abbe_comp_init(&c, NULL, NULL), ABBE_E_ARG);
    cfg.fade_cycles = 0;
    assert_int_equal(abbe_comp_init(&c, &cfg, NULL), ABBE_E_ARG);
    cfg = config();
    cfg.stale_cycles = 0;
    assert_int_equal(abbe_comp_init(&c, &cfg, NULL), ABBE_E_ARG);
    cfg = config();
    cfg.limit_nm[1] = cfg.warn_nm[1] - 1;
    assert_int_equal(abbe_comp_init(&c, &cfg, NULL), ABBE_E_ARG);
    cfg = config();
    cfg.rate_nm_per_cycle[2] = 0;
    assert_int_equal(abbe_comp_init(&c, &cfg, NULL), ABBE_E_ARG);
    cfg = config();
    cfg.axis_sign[0] = 0;
    assert_int_equal(abbe_comp_init(&c, &cfg, NULL), ABBE_E_ARG);
    cfg = config();
    assert_int_equal(abbe_comp_init(&c, &cfg, NULL), ABBE_OK);
}

/* Disabled: zero. Enabled: ramps to +20 um without a jump; the direction state
 * starts at 0, so backlash adds nothing until the axis moves. */
static void test_fade_in_and_out(void **state)
{
    (void)state;
    for (int i = 0; i < 5; i++) step(100.0, 0, 1, 0);
    assert_int_equal(fx.out.corr_nm[0], 0);
    assert_int_equal(fx.out.target_nm[0], 20000);
    assert_int_equal(fx.out.state, ABBE_COMP_OFF);
    assert_int_equal(abbe_comp_enable(&fx.comp), ABBE_OK);
    uint32_t seen = 0;
    for (int i = 0; i < 40; i++) seen |= step(100.0, 0, 1, 0);
    assert_true(seen & ABBE_FLAG_FADING);
    assert_int_equal(fx.out.corr_nm[0], 20000);
    assert_int_equal(fx.out.state, ABBE_COMP_ON);
    assert_int_equal(fx.out.flags & ABBE_FLAG_FADING, 0);
    assert_int_equal(abbe_comp_disable(&fx.comp), ABBE_OK);
    for (int i = 0; i < 40; i++) step(100.0, 0, 1, 0);
    assert_int_equal(fx.out.corr_nm[0], 0);
    assert_true(fx.max_step <= 2000); /* fade step 20000/10 at most */
}

static void test_rate_limit_clips(void **state)
{
    (void)state;
    abbe_comp_config_t c = config();
    c.fade_cycles = 1; /* instant gain: only the rate limit shapes the output */
    assert_int_equal(abbe_comp_init(&fx.comp, &c, &fx.a), ABBE_OK);
    abbe_comp_enable(&fx.comp);
    uint32_t f = step(100.0, 0, 1, 0);
    assert_true(f & ABBE_FLAG_RATE_LIMITED);
    assert_int_equal(fx.out.corr_nm[0], 1000);
    for (int i = 0; i < 19; i++) step(100.0, 0, 1, 0);
    assert_int_equal(fx.out.corr_nm[0], 20000);
    f = step(100.0, 0, 1, 0);
    assert_int_equal(f & ABBE_FLAG_RATE_LIMITED, 0);
    assert_int_equal(fx.max_step, 1000);
    assert_true(abbe_comp_stats(&fx.comp).rate_limited >= 19u);
}

/* Over the error limit: fault latched, fade to zero, reported; reset then
 * enable resumes. Over the warning limit only: flagged, still applied. */
static void test_limits(void **state)
{
    (void)state;
    abbe_comp_config_t c = config();
    c.warn_nm[0] = 15000;
    c.limit_nm[0] = 25000;
    assert_int_equal(abbe_comp_init(&fx.comp, &c, &fx.a), ABBE_OK);
    abbe_comp_enable(&fx.comp);
    for (int i = 0; i < 30; i++) step(100.0, 0, 1, 0);
    assert_true(fx.out.flags & ABBE_FLAG_WARN);
    assert_int_equal(fx.out.flags & ABBE_FLAG_LIMIT, 0);
    assert_int_equal(fx.out.corr_nm[0], 20000);
    /* table B asks for 30 um: over the limit */
    assert_int_equal(abbe_comp_swap_model(&fx.comp, &fx.b), ABBE_OK);
    uint32_t f = step(100.0, 0, 1, 0);
    assert_true(f & ABBE_FLAG_MODEL_SWAPPED);
    assert_true(f & ABBE_FLAG_LIMIT);
    assert_int_equal(fx.out.state, ABBE_COMP_FAULT);
    for (int i = 0; i < 40; i++) step(100.0, 0, 1, 0);
    assert_int_equal(fx.out.corr_nm[0], 0);
    assert_true(fx.out.flags & ABBE_FLAG_LIMIT);
    assert_int_equal(abbe_comp_stats(&fx.comp).limit_trips, 1u);
    /* back to table A, reset, enable */
    abbe_comp_swap_model(&fx.comp, &fx.a);
    assert_int_equal(abbe_comp_reset(&fx.comp), ABBE_OK);
    step(100.0, 0, 1, 0);
    assert_int_equal(fx.out.state, ABBE_COMP_OFF);
    abbe_comp_enable(&fx.comp);
    for (int i = 0; i < 40; i++) step(100.0, 0, 1, 0);
    assert_int_equal(fx.out.state, ABBE_COMP_ON);
    assert_int_equal(fx.out.corr_nm[0], 20000);
    assert_true(fx.max_step <= 2000);
}

/* A target beyond the error limit trips the fault; the output must never move
 * toward it, not even in the cycle that trips, whatever the rate limit: it
 * fades out from where it was, monotonically (found by fuzz_modbus_regs). */
static void test_limit_trip_never_grows_the_output(void **state)
{
    (void)state;
    abbe_comp_config_t c = config();
    c.warn_nm[0] = 15000;
    c.limit_nm[0] = 25000;
    c.rate_nm_per_cycle[0] = 100000; /* no rate limit to hide behind */
    assert_int_equal(abbe_comp_init(&fx.comp, &c, &fx.a), ABBE_OK);
    abbe_comp_enable(&fx.comp);
    for (int i = 0; i < 5; i++) step(100.0, 0, 1, 0); /* fading in toward 20 um */
    int32_t before = fx.out.corr_nm[0];
    assert_true(before > 0 && before < 20000);
    fx.max_step = 0;
    assert_int_equal(abbe_comp_swap_model(&fx.comp, &fx.b), ABBE_OK); /* asks for 30 um */
    int32_t last = before;
    for (int i = 0; i < 40; i++) {
        step(100.0, 0, 1, 0);
        assert_int_equal(fx.out.state, ABBE_COMP_FAULT);
        assert_true(fx.out.corr_nm[0] >= 0 && fx.out.corr_nm[0] <= last);
        assert_true(fx.out.corr_nm[0] <= c.limit_nm[0]);
        last = fx.out.corr_nm[0];
    }
    assert_int_equal(fx.out.corr_nm[0], 0);
    /* the fade-out takes fade_cycles from the held output: no step beyond it */
    assert_true(fx.max_step <= before / c.fade_cycles + 1);
}

/* No fresh input for stale_cycles: flagged, faded out; fresh again: back in. */
static void test_stale_watchdog(void **state)
{
    (void)state;
    abbe_comp_enable(&fx.comp);
    for (int i = 0; i < 30; i++) step(100.0, 0, 1, 0);
    assert_int_equal(fx.out.corr_nm[0], 20000);
    uint32_t f = step(100.0, 0, 0, 0);
    assert_true(f & ABBE_FLAG_INPUT_INVALID);
    assert_int_equal(f & ABBE_FLAG_STALE, 0);
    assert_int_equal(fx.out.corr_nm[0], 20000); /* one missed cycle: held */
    step(100.0, 0, 0, 0);
    f = step(100.0, 0, 0, 0);
    assert_true(f & ABBE_FLAG_STALE);
    for (int i = 0; i < 30; i++) step(100.0, 0, 0, 0);
    assert_int_equal(fx.out.corr_nm[0], 0);
    assert_int_equal(abbe_comp_stats(&fx.comp).stale_events, 1u);
    f = step(100.0, 0, 1, 0);
    assert_int_equal(f & ABBE_FLAG_STALE, 0);
    for (int i = 0; i < 30; i++) step(100.0, 0, 1, 0);
    assert_int_equal(fx.out.corr_nm[0], 20000);
    assert_true(fx.max_step <= 2000);
}

/* An axis fault fades that axis only. */
static void test_axis_fault(void **state)
{
    (void)state;
    abbe_comp_config_t c = config();
    assert_int_equal(abbe_comp_init(&fx.comp, &c, &fx.a), ABBE_OK);
    abbe_comp_enable(&fx.comp);
    for (int i = 0; i < 30; i++) step(100.0, 0, 1, 0);
    uint32_t f = step(100.0, 0, 1, 0x1);
    assert_true(f & ABBE_FLAG_AXIS_FAULT);
    for (int i = 0; i < 30; i++) step(100.0, 0, 1, 0x1);
    assert_int_equal(fx.out.corr_nm[0], 0);
    assert_int_equal(fx.out.state, ABBE_COMP_ON);
    for (int i = 0; i < 30; i++) step(100.0, 0, 1, 0);
    assert_int_equal(fx.out.corr_nm[0], 20000);
    assert_true(fx.max_step <= 2000);
}

/* A bad blob never replaces the running model; a good one takes effect at the
 * next cycle boundary, not before. */
static void test_model_swap(void **state)
{
    (void)state;
    abbe_comp_enable(&fx.comp);
    for (int i = 0; i < 30; i++) step(100.0, 0, 1, 0);
    memcpy(blob_bad, blob_b, size_b);
    blob_bad[size_b - 9] ^= 0x10;
    assert_int_equal(abbe_comp_load_model(&fx.comp, &fx.spare, blob_bad, size_b), ABBE_E_CRC);
    assert_ptr_equal(abbe_comp_model(&fx.comp), &fx.a);
    step(100.0, 0, 1, 0);
    assert_int_equal(fx.out.flags & ABBE_FLAG_MODEL_SWAPPED, 0);
    assert_int_equal(fx.out.target_nm[0], 20000);
    /* the running model's own slot cannot be overwritten */
    assert_int_equal(abbe_comp_load_model(&fx.comp, &fx.a, blob_b, size_b), ABBE_E_ARG);
    assert_int_equal(abbe_comp_load_model(&fx.comp, &fx.spare, blob_b, size_b), ABBE_OK);
    assert_ptr_equal(abbe_comp_model(&fx.comp), &fx.a); /* not yet */
    uint32_t f = step(100.0, 0, 1, 0);
    assert_true(f & ABBE_FLAG_MODEL_SWAPPED);
    assert_ptr_equal(abbe_comp_model(&fx.comp), &fx.spare);
    assert_int_equal(fx.out.target_nm[0], -30000);
    for (int i = 0; i < 60; i++) step(100.0, 0, 1, 0);
    assert_int_equal(fx.out.corr_nm[0], -30000);
    assert_true(fx.max_step <= 1000); /* the 50 um change went through the rate limit */
    assert_int_equal(abbe_comp_stats(&fx.comp).model_swaps, 1u);
}

/* Without a model: output zero, flagged; a model arriving fades in. */
static void test_no_model(void **state)
{
    (void)state;
    abbe_comp_config_t c = config();
    assert_int_equal(abbe_comp_init(&fx.comp, &c, NULL), ABBE_OK);
    abbe_comp_enable(&fx.comp);
    uint32_t f = step(100.0, 0, 1, 0);
    assert_true(f & ABBE_FLAG_NO_MODEL);
    assert_int_equal(f & ABBE_FLAG_INPUT_INVALID, 0);
    assert_int_equal(fx.out.corr_nm[0], 0);
    abbe_comp_swap_model(&fx.comp, &fx.a);
    for (int i = 0; i < 30; i++) step(100.0, 0, 1, 0);
    assert_int_equal(fx.out.corr_nm[0], 20000);
}

/* Backlash: moving + for a full take-up gives +B/2 on d_x, i.e. a correction of
 * +(20 + 5) um; reversing, it ramps over 1 mm to +(20 - 5) um, never a step. */
static void test_backlash_direction_tracking(void **state)
{
    (void)state;
    abbe_comp_config_t c = config();
    c.rate_nm_per_cycle[0] = 100000;
    c.fade_cycles = 1;
    assert_int_equal(abbe_comp_init(&fx.comp, &c, &fx.a), ABBE_OK);
    abbe_comp_enable(&fx.comp);
    double x = 100.0;
    for (int i = 0; i < 30; i++, x += 0.1) step(x, 1, 1, 0);
    assert_int_equal(fx.out.corr_nm[0], 25000);
    fx.max_step = 0;
    int32_t prev = fx.out.corr_nm[0];
    for (int i = 0; i < 30; i++, x -= 0.05) {
        step(x, -1, 1, 0);
        /* 0.05 mm of a 1 mm take-up is a tenth of the 10 um swing: 1 um a cycle */
        assert_true(abs(fx.out.corr_nm[0] - prev) <= 1001);
        prev = fx.out.corr_nm[0];
    }
    assert_int_equal(fx.out.corr_nm[0], 15000);
    /* standstill keeps the state */
    for (int i = 0; i < 5; i++) step(x, 0, 1, 0);
    assert_int_equal(fx.out.corr_nm[0], 15000);
}

/* A position-dependent reversal (format 1.1) follows the same direction state:
 * table C is table A with a reversal block R = 4 u um on X (total 10 + 4u),
 * u = (2x - 500) / 500. Moving + the correction is 20 + R(x) / 2, after a
 * reversal it ramps over the take-up to 20 - R(x) / 2; the q and f32 steps agree. */
static void test_reversal_block_direction_tracking(void **state)
{
    (void)state;
    static uint8_t blob_c[4096] __attribute__((aligned(8)));
    static int32_t rev[2];
    tb_table_t t;
    tb_init(&t);
    t.features = ABBE_FEATURE_BACKLASH | ABBE_FEATURE_REVERSAL;
    for (int j = 0; j < 3; j++) t.axis[j].takeup_nm = NM(1);
    t.axis[0].backlash_q8 = LIN_Q(10.0);
    t.axis[0].term_mask = 1u << ABBE_TERM_DX;
    t.axis[0].trend_degree = 0;
    t.axis[0].coef_q = coef_a;
    rev[0] = 0;
    rev[1] = LIN_Q(4.0);
    t.axis[0].reversal_rows = 2;
    t.axis[0].reversal_q = rev;
    size_t n = tb_build(&t, blob_c, sizeof blob_c);
    abbe_model_t mc;
    assert_int_equal(abbe_model_load(&mc, blob_c, n), ABBE_OK);
    abbe_comp_config_t c = config();
    c.rate_nm_per_cycle[0] = 100000;
    c.fade_cycles = 1;
    abbe_comp_t comp_f;
    assert_int_equal(abbe_comp_init(&fx.comp, &c, &mc), ABBE_OK);
    assert_int_equal(abbe_comp_init(&comp_f, &c, &mc), ABBE_OK);
    abbe_comp_enable(&fx.comp);
    abbe_comp_enable(&comp_f);
    double x = 100.0;
    abbe_comp_output_t out_f;
    for (int i = 0; i < 60; i++) {
        int8_t dir = i < 30 ? 1 : -1;
        if (i == 30) {
            fx.max_step = 0; /* the reversal from here on */
        }
        step(x, dir, 1, 0);
        abbe_comp_input_f32_t in;
        memset(&in, 0, sizeof in);
        in.pos_mm[0] = (float)x;
        in.temp_c[0] = in.temp_c[1] = in.temp_c[2] = 20.0f;
        in.dir[0] = dir;
        in.fresh = 1;
        assert_int_equal(abbe_comp_step_f32(&comp_f, &in, &out_f), ABBE_OK);
        assert_true(abs(out_f.corr_nm[0] - fx.out.corr_nm[0]) <= 1);
        double r_um = 10.0 + 4.0 * (2.0 * x - 500.0) / 500.0;
        if (i == 29) { /* moving +, state +1 */
            assert_true(fabs(fx.out.corr_nm[0] - 1000.0 * (20.0 + r_um / 2.0)) <= 1.0);
        }
        if (i == 59) { /* 1.5 mm back: state -1 */
            assert_true(fabs(fx.out.corr_nm[0] - 1000.0 * (20.0 - r_um / 2.0)) <= 1.0);
        }
        x += i < 29 ? 0.1 : -0.05;
    }
    assert_true(fx.max_step <= 1100); /* the reversal ramps (about 0.8 um a cycle), never a step */
}

/* The float step: NaN positions are bad input (held, then stale), not a crash,
 * and a good float cycle gives the same correction as the q step. */
static void test_f32_step(void **state)
{
    (void)state;
    abbe_comp_enable(&fx.comp);
    abbe_comp_input_f32_t in;
    memset(&in, 0, sizeof in);
    in.pos_mm[0] = 100.0f;
    in.fresh = 1;
    for (int i = 0; i < 30; i++) assert_int_equal(abbe_comp_step_f32(&fx.comp, &in, &fx.out), ABBE_OK);
    assert_int_equal(fx.out.corr_nm[0], 20000);
    in.pos_mm[1] = NAN;
    assert_int_equal(abbe_comp_step_f32(&fx.comp, &in, &fx.out), ABBE_OK);
    assert_true(fx.out.flags & ABBE_FLAG_INPUT_INVALID);
    assert_int_equal(fx.out.corr_nm[0], 20000);
    for (int i = 0; i < 40; i++) abbe_comp_step_f32(&fx.comp, &in, &fx.out);
    assert_true(fx.out.flags & ABBE_FLAG_STALE);
    assert_int_equal(fx.out.corr_nm[0], 0);
    assert_int_equal(abbe_comp_step_f32(NULL, &in, &fx.out), ABBE_E_ARG);
    assert_int_equal(abbe_comp_step_q(&fx.comp, NULL, &fx.out), ABBE_E_ARG);
}

/* Limits and rates change while running: no jump, the direction state and
 * counters survive, a bad config is refused and the old one stays. */
static void test_set_config_while_running(void **state)
{
    (void)state;
    abbe_comp_config_t c = config();
    c.fade_cycles = 1;
    c.rate_nm_per_cycle[0] = 100000;
    assert_int_equal(abbe_comp_init(&fx.comp, &c, &fx.a), ABBE_OK);
    abbe_comp_enable(&fx.comp);
    double x = 100.0;
    for (int i = 0; i < 30; i++, x += 0.1) step(x, 1, 1, 0);
    assert_int_equal(fx.out.corr_nm[0], 25000); /* 20 um + B/2 moving + */
    uint32_t cycles = abbe_comp_stats(&fx.comp).cycles;

    abbe_comp_config_t bad = c;
    bad.rate_nm_per_cycle[1] = 0;
    assert_int_equal(abbe_comp_set_config(&fx.comp, &bad), ABBE_E_ARG);
    assert_int_equal(abbe_comp_set_config(NULL, &c), ABBE_E_ARG);

    c.rate_nm_per_cycle[0] = 10;
    c.warn_nm[0] = 24000;
    assert_int_equal(abbe_comp_set_config(&fx.comp, &c), ABBE_OK);
    fx.max_step = 0;
    uint32_t f = step(x, 1, 1, 0);
    assert_int_equal(fx.out.corr_nm[0], 25000); /* no jump, direction state kept */
    assert_true(f & ABBE_FLAG_WARN);             /* the new warning limit applies */
    assert_int_equal(abbe_comp_stats(&fx.comp).cycles, cycles + 1u);
    for (int i = 0; i < 20; i++, x -= 0.05) step(x, -1, 1, 0);
    assert_true(fx.max_step <= 10); /* the new rate limit shapes the reversal */
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup(test_config_checked, setup),
        cmocka_unit_test_setup(test_fade_in_and_out, setup),
        cmocka_unit_test_setup(test_rate_limit_clips, setup),
        cmocka_unit_test_setup(test_limits, setup),
        cmocka_unit_test_setup(test_limit_trip_never_grows_the_output, setup),
        cmocka_unit_test_setup(test_stale_watchdog, setup),
        cmocka_unit_test_setup(test_axis_fault, setup),
        cmocka_unit_test_setup(test_model_swap, setup),
        cmocka_unit_test_setup(test_no_model, setup),
        cmocka_unit_test_setup(test_backlash_direction_tracking, setup),
        cmocka_unit_test_setup(test_reversal_block_direction_tracking, setup),
        cmocka_unit_test_setup(test_f32_step, setup),
        cmocka_unit_test_setup(test_set_config_while_running, setup),
    };
    return cmocka_run_group_tests_name("comp", tests, NULL, NULL);
}
