/* Tests of the LinuxCNC port's C (abbe_lcnc, abbe_lcnc_file) without LinuxCNC.
 *
 * LinuxCNC's side of the external offsets is modelled here from its
 * documented behaviour (docs/src/motion/external-offsets.adoc and
 * src/emc/motion/axis.c, axis_plan_external_offsets): each servo period the
 * change of axis.L.eoffset-counts since the previous period, times
 * eoffset-scale, is added to the requested offset, but only while
 * eoffset-enable is set, eoffset-clear is not, every joint is homed and motion
 * is enabled; at machine-on the requested offset is set to zero.
 */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "abbe_lcnc.h"
#include "abbe_lcnc_file.h"
#include "golden_data.h"
#include "golden_five.h"
#include "golden_thermal.h"
#include "thermal_stuck.h"

#define PERIOD_NS 1000000L

/* ---- LinuxCNC's external-offset register, per axis ---------------------- */

typedef struct {
    int32_t old_counts;
    int first_pass;
    double request; /* axis.L.eoffset-request, machine units */
} lc_axis_t;

static void lc_init(lc_axis_t *a)
{
    a->old_counts = 0;
    a->first_pass = 1;
    a->request = 0.0;
}

/* One motion-controller period. */
static void lc_cycle(lc_axis_t *a, int32_t counts, double scale, int machine_on, int enabling,
                     int homed)
{
    if (enabling) {
        a->request = 0.0; /* axis_initialize_external_offsets() */
    }
    uint32_t du = (uint32_t)counts - (uint32_t)a->old_counts;
    int32_t delta;
    memcpy(&delta, &du, sizeof delta);
    a->old_counts = counts;
    if (a->first_pass) {
        a->first_pass = 0;
        return;
    }
    if (delta == 0 || !homed || !machine_on) {
        return;
    }
    a->request += (double)delta * scale;
}

/* ---- helpers --------------------------------------------------------------- */

static const abbe_golden_table_t *golden(const char *name)
{
    for (uint32_t i = 0; i < abbe_golden_table_count; i++) {
        if (strcmp(abbe_golden_tables[i].name, name) == 0) {
            return &abbe_golden_tables[i];
        }
    }
    fail_msg("golden table %s missing", name);
    return NULL;
}

/* The golden blobs are const arrays; the port wants 4-byte aligned bytes that
 * outlive it: copy into static aligned storage. */
static uint32_t blob_store[4][ABBE_LCNC_TABLE_MAX_BYTES / 4];

static const void *aligned_blob(unsigned slot, const abbe_golden_table_t *t)
{
    assert_true(t->blob_size <= sizeof blob_store[slot]);
    memcpy(blob_store[slot], t->blob, t->blob_size);
    return blob_store[slot];
}

static abbe_lcnc_t port;

/* Default parameters with a short fade (20 ms) and a fast rate limit (10 mm/s), so
 * that faults and fades play out in a few dozen periods. */
static void quick_params(abbe_lcnc_params_t *p)
{
    abbe_lcnc_default_params(p);
    p->fade_s = 0.02;
    p->rate_mm_per_s[0] = p->rate_mm_per_s[1] = p->rate_mm_per_s[2] = 10.0;
}

static void setup_port(abbe_lcnc_variant_t v, const abbe_lcnc_params_t *p, const char *table)
{
    const abbe_golden_table_t *t = golden(table);
    assert_int_equal(abbe_lcnc_init(&port, v, p, PERIOD_NS), ABBE_OK);
    assert_int_equal(abbe_lcnc_add_table(&port, aligned_blob(0, t), t->blob_size), ABBE_OK);
}

static void circle(unsigned k, double pos[3])
{
    /* 100 mm radius around the paper table's work volume centre, 2 s a turn */
    double a = 2.0 * 3.14159265358979323846 * (double)k / 2000.0;
    pos[0] = 250.0 + 100.0 * cos(a);
    pos[1] = -200.0 + 100.0 * sin(a);
    pos[2] = -150.0 + 20.0 * sin(0.5 * a);
}

static void input_at(abbe_lcnc_input_t *in, unsigned k)
{
    memset(in, 0, sizeof *in);
    circle(k, in->pos_mm);
    for (unsigned j = 0; j < 3; j++) {
        in->temp_c[j] = 20.0;
    }
    in->enable = 1;
    in->homed = 1;
    in->machine_on = 1;
}

static int32_t mm_nm(double mm)
{
    return (int32_t)lround(mm * 1e6);
}

/* ---- parameters --------------------------------------------------------------- */

static void test_params_convert(void **state)
{
    (void)state;
    abbe_lcnc_params_t p;
    abbe_lcnc_default_params(&p);
    abbe_comp_config_t c;
    assert_int_equal(abbe_lcnc_params_to_config(&p, PERIOD_NS, &c), ABBE_OK);
    for (unsigned j = 0; j < 3; j++) {
        assert_int_equal(c.warn_nm[j], 50000);
        assert_int_equal(c.limit_nm[j], 100000);
        assert_int_equal(c.rate_nm_per_cycle[j], 1000); /* 1 mm/s at 1 kHz */
        assert_int_equal(c.axis_sign[j], 1);
    }
    assert_int_equal(c.fade_cycles, 500);
    assert_int_equal(c.stale_cycles, 10);

    /* 250 us servo period: a quarter of the rate, four times the cycles. */
    assert_int_equal(abbe_lcnc_params_to_config(&p, 250000L, &c), ABBE_OK);
    assert_int_equal(c.rate_nm_per_cycle[0], 250);
    assert_int_equal(c.fade_cycles, 2000);

    /* fade 0 s is one cycle; a tiny positive rate is at least 1 nm/cycle */
    p.fade_s = 0.0;
    p.rate_mm_per_s[1] = 1e-9;
    assert_int_equal(abbe_lcnc_params_to_config(&p, PERIOD_NS, &c), ABBE_OK);
    assert_int_equal(c.fade_cycles, 1);
    assert_int_equal(c.rate_nm_per_cycle[1], 1);
}

static void test_params_rejected(void **state)
{
    (void)state;
    abbe_lcnc_params_t good, p;
    abbe_lcnc_default_params(&good);
    abbe_comp_config_t c, before;
    memset(&before, 0x5A, sizeof before);
    const double nan = strtod("nan", NULL);

    p = good; p.warn_mm[0] = 0.0;
    c = before; assert_int_equal(abbe_lcnc_params_to_config(&p, PERIOD_NS, &c), ABBE_E_ARG);
    assert_memory_equal(&c, &before, sizeof c);
    p = good; p.warn_mm[1] = nan;
    assert_int_equal(abbe_lcnc_params_to_config(&p, PERIOD_NS, &c), ABBE_E_ARG);
    p = good; p.limit_mm[2] = 0.01; /* below warn */
    assert_int_equal(abbe_lcnc_params_to_config(&p, PERIOD_NS, &c), ABBE_E_ARG);
    p = good; p.limit_mm[0] = 3000.0; /* beyond int32 nm */
    assert_int_equal(abbe_lcnc_params_to_config(&p, PERIOD_NS, &c), ABBE_E_ARG);
    p = good; p.rate_mm_per_s[0] = -1.0;
    assert_int_equal(abbe_lcnc_params_to_config(&p, PERIOD_NS, &c), ABBE_E_ARG);
    p = good; p.rate_mm_per_s[0] = HUGE_VAL;
    assert_int_equal(abbe_lcnc_params_to_config(&p, PERIOD_NS, &c), ABBE_E_ARG);
    p = good; p.sign[2] = 0;
    assert_int_equal(abbe_lcnc_params_to_config(&p, PERIOD_NS, &c), ABBE_E_ARG);
    p = good; p.fade_s = 70.0; /* 70000 cycles > 65535 */
    assert_int_equal(abbe_lcnc_params_to_config(&p, PERIOD_NS, &c), ABBE_E_ARG);
    p = good; p.stale_s = -0.1;
    assert_int_equal(abbe_lcnc_params_to_config(&p, PERIOD_NS, &c), ABBE_E_ARG);
    p = good; p.dir_deadband_mm = nan;
    assert_int_equal(abbe_lcnc_params_to_config(&p, PERIOD_NS, &c), ABBE_E_ARG);
    p = good; p.machine_unit_mm = 0.0;
    assert_int_equal(abbe_lcnc_params_to_config(&p, PERIOD_NS, &c), ABBE_E_ARG);
    assert_int_equal(abbe_lcnc_params_to_config(&good, 0L, &c), ABBE_E_ARG);
    assert_int_equal(abbe_lcnc_init(&port, (abbe_lcnc_variant_t)7, &good, PERIOD_NS), ABBE_E_ARG);
}

/* A bad parameter at run time: flagged, counted, the running configuration
 * stays; once corrected the flag clears. */
static void test_runtime_bad_param(void **state)
{
    (void)state;
    abbe_lcnc_params_t p;
    abbe_lcnc_default_params(&p);
    setup_port(ABBE_LCNC_VARIANT_Q, &p, "paper");
    abbe_lcnc_input_t in;
    abbe_lcnc_output_t out;
    input_at(&in, 0);
    abbe_lcnc_step(&port, &p, PERIOD_NS, &in, &out);
    assert_false(out.flags & ABBE_LCNC_FLAG_CONFIG);
    p.limit_mm[1] = 0.001; /* below warn */
    abbe_lcnc_step(&port, &p, PERIOD_NS, &in, &out);
    assert_true(out.flags & ABBE_LCNC_FLAG_CONFIG);
    assert_true(out.config_error);
    assert_int_equal(out.config_errors, 1);
    abbe_lcnc_step(&port, &p, PERIOD_NS, &in, &out); /* same bad set: counted once */
    assert_int_equal(out.config_errors, 1);
    assert_int_equal(out.state, ABBE_COMP_ON); /* the old limits still apply: no fault */
    p.limit_mm[1] = 0.1;
    abbe_lcnc_step(&port, &p, PERIOD_NS, &in, &out);
    assert_false(out.config_error);
}

/* ---- the external-offset register, against the model of LinuxCNC ------------ */

typedef struct {
    unsigned from, to; /* cycles [from, to) */
    int machine_on, homed, enable;
} phase_t;

static int level(const phase_t *ph, size_t n, unsigned k, int which)
{
    for (size_t i = 0; i < n; i++) {
        if (k >= ph[i].from && k < ph[i].to) {
            return which == 0 ? ph[i].machine_on : (which == 1 ? ph[i].homed : ph[i].enable);
        }
    }
    return 0;
}

/* Run a machine history; abbe runs after (after_motion = 1) or before motion
 * in the thread. Checks every cycle that the port's mirror equals LinuxCNC's
 * register, that the register never moves by more than the rate limit in a
 * cycle, and that it equals the correction wherever the port has caught up. */
static void run_history(int after_motion, abbe_lcnc_variant_t v)
{
    static const phase_t ph[] = {
        {0, 10, 0, 0, 1},     /* machine off, not homed, enable already high */
        {10, 20, 1, 0, 1},    /* machine on, homing */
        {20, 300, 1, 1, 1},   /* homed: fade in, run */
        {300, 304, 0, 1, 1},  /* e-stop mid-run, back on after 4 ms */
        {304, 420, 1, 1, 1},
        {420, 440, 1, 0, 1},  /* a joint unhomed, rehomed 20 ms later */
        {440, 700, 1, 1, 1},
        {700, 900, 1, 1, 0},  /* enable off: fade out */
        {900, 1000, 0, 1, 0}, /* machine off */
        {1000, 1400, 1, 1, 1} /* and on again */
    };
    const size_t n_ph = sizeof ph / sizeof ph[0];
    abbe_lcnc_params_t p;
    abbe_lcnc_default_params(&p);
    p.fade_s = 0.1;
    p.rate_mm_per_s[0] = p.rate_mm_per_s[1] = p.rate_mm_per_s[2] = 2.0;
    setup_port(v, &p, "paper");
    lc_axis_t lc[3];
    for (unsigned j = 0; j < 3; j++) {
        lc_init(&lc[j]);
    }
    int32_t counts[3] = {0, 0, 0};
    double scale = 1e-6;
    int prev_on = 0;
    int seen_on = 0, seen_homed = 0; /* motion's pins as the port reads them */
    unsigned caught_up = 0, hold_cycles = 0;
    abbe_lcnc_output_t out;
    memset(&out, 0, sizeof out);
    for (unsigned k = 0; k < 1400; k++) {
        int on = level(ph, n_ph, k, 0), homed = level(ph, n_ph, k, 1);
        int enabling = on && !prev_on;
        prev_on = on;
        double before[3];
        for (unsigned j = 0; j < 3; j++) {
            before[j] = lc[j].request;
        }
        abbe_lcnc_input_t in;
        input_at(&in, k);
        in.enable = (uint8_t)level(ph, n_ph, k, 2);
        if (after_motion) {
            for (unsigned j = 0; j < 3; j++) {
                lc_cycle(&lc[j], counts[j], scale, on, enabling, homed);
            }
            in.machine_on = (uint8_t)on;
            in.homed = (uint8_t)homed;
            abbe_lcnc_step(&port, &p, PERIOD_NS, &in, &out);
        } else {
            in.machine_on = (uint8_t)seen_on; /* pins from motion's previous period */
            in.homed = (uint8_t)seen_homed;
            abbe_lcnc_step(&port, &p, PERIOD_NS, &in, &out);
            for (unsigned j = 0; j < 3; j++) {
                lc_cycle(&lc[j], out.counts[j], out.eoffset_scale, on, enabling, homed);
            }
        }
        seen_on = on;
        seen_homed = homed;
        int32_t written[3]; /* the change written this period */
        for (unsigned j = 0; j < 3; j++) {
            written[j] = (int32_t)((uint32_t)out.counts[j] - (uint32_t)counts[j]);
            counts[j] = out.counts[j];
            scale = out.eoffset_scale;
            /* The mirror is LinuxCNC's register as of the motion period whose
             * pins the port read (this one if it runs after motion). */
            double reg = after_motion ? lc[j].request : before[j];
            if (fabs(out.offset_mm[j] - reg) > 1e-9) {
                fail_msg("cycle %u axis %u: port thinks LinuxCNC holds %.9f mm, it holds %.9f mm",
                         k, j, out.offset_mm[j], reg);
            }
            double step = fabs(lc[j].request - before[j]);
            if (step > 2.0e-3 + 1e-9 && !enabling) {
                fail_msg("cycle %u axis %u: LinuxCNC's offset moved %.6f mm in one period", k, j, step);
            }
        }
        if (!(out.flags & ABBE_LCNC_FLAG_CATCHUP) && !(out.flags & ABBE_LCNC_FLAG_HOLD)) {
            for (unsigned j = 0; j < 3; j++) {
                /* caught up: what LinuxCNC will hold after its next period is the correction */
                assert_int_equal(mm_nm(out.offset_mm[j]) + written[j], mm_nm(out.corr_mm[j]));
            }
            caught_up++;
        }
        if (out.flags & ABBE_LCNC_FLAG_HOLD) {
            hold_cycles++;
        }
    }
    /* The run ended with the machine on, enabled and faded in: LinuxCNC holds
     * the correction, and the correction is the model's. */
    for (unsigned j = 0; j < 3; j++) {
        assert_true(fabs(out.corr_mm[j]) > 1e-4); /* the paper table errs by tens of um here */
        /* LinuxCNC's register lags the correction by the change of the last period only */
        assert_true(fabs(lc[j].request - out.corr_mm[j]) <= 2.0e-3 + 1e-9);
        assert_true(fabs(out.corr_mm[j] - out.target_mm[j]) < 1e-9);
    }
    assert_false(out.flags & ABBE_LCNC_FLAG_CATCHUP);
    assert_true(caught_up > 1000);
    assert_true(hold_cycles >= 20 + 4 + 20 + 100);
}

static void test_register_after_motion_q(void **state)
{
    (void)state;
    run_history(1, ABBE_LCNC_VARIANT_Q);
}

static void test_register_before_motion_q(void **state)
{
    (void)state;
    run_history(0, ABBE_LCNC_VARIANT_Q);
}

static void test_register_after_motion_f32(void **state)
{
    (void)state;
    run_history(1, ABBE_LCNC_VARIANT_F32);
}

/* ---- enable logic, faults, reset --------------------------------------------- */

static void test_homed_low_gives_zero(void **state)
{
    (void)state;
    abbe_lcnc_params_t p;
    abbe_lcnc_default_params(&p);
    setup_port(ABBE_LCNC_VARIANT_Q, &p, "paper");
    abbe_lcnc_input_t in;
    abbe_lcnc_output_t out;
    for (unsigned k = 0; k < 2000; k++) {
        input_at(&in, k);
        in.homed = 0;
        abbe_lcnc_step(&port, &p, PERIOD_NS, &in, &out);
        for (unsigned j = 0; j < 3; j++) {
            assert_true(out.corr_mm[j] == 0.0);
            assert_int_equal(out.counts[j], 0);
            assert_true(fabs(out.target_mm[j]) > 0.0 || k == 0); /* the model is still evaluated */
        }
        assert_int_equal(out.state, ABBE_COMP_OFF);
        assert_true(out.flags & ABBE_LCNC_FLAG_HOLD);
    }
}

/* A limit trip latches a fault and fades out; reset with enable high resumes. */
static void test_fault_and_reset(void **state)
{
    (void)state;
    abbe_lcnc_params_t p;
    quick_params(&p);
    setup_port(ABBE_LCNC_VARIANT_Q, &p, "paper");
    abbe_lcnc_input_t in;
    abbe_lcnc_output_t out;
    unsigned k = 0;
    for (; k < 100; k++) {
        input_at(&in, 0);
        abbe_lcnc_step(&port, &p, PERIOD_NS, &in, &out);
    }
    assert_int_equal(out.state, ABBE_COMP_ON);
    double full = out.corr_mm[1];
    assert_true(fabs(full) > 1e-4);
    /* an error limit below the correction, changed at run time */
    for (unsigned j = 0; j < 3; j++) {
        p.warn_mm[j] = 1e-6;
        p.limit_mm[j] = 2e-6;
    }
    double prev = full;
    for (unsigned i = 0; i < 100; i++, k++) {
        abbe_lcnc_step(&port, &p, PERIOD_NS, &in, &out);
        assert_true(fabs(out.corr_mm[1] - prev) <= fabs(full) / 20.0 + 1e-9); /* a fade, not a jump */
        prev = out.corr_mm[1];
    }
    assert_int_equal(out.state, ABBE_COMP_FAULT);
    assert_true(out.fault);
    assert_int_equal(out.stats.limit_trips, 1);
    assert_true(out.corr_mm[1] == 0.0);
    /* reset alone with the limits still too low: trips again */
    in.reset = 1;
    abbe_lcnc_step(&port, &p, PERIOD_NS, &in, &out);
    in.reset = 0;
    abbe_lcnc_step(&port, &p, PERIOD_NS, &in, &out);
    assert_int_equal(out.state, ABBE_COMP_FAULT);
    assert_int_equal(out.stats.limit_trips, 2);
    /* limits back, reset: fades in again */
    quick_params(&p);
    in.reset = 1;
    abbe_lcnc_step(&port, &p, PERIOD_NS, &in, &out);
    in.reset = 0;
    for (unsigned i = 0; i < 100; i++) {
        abbe_lcnc_step(&port, &p, PERIOD_NS, &in, &out);
    }
    assert_int_equal(out.state, ABBE_COMP_ON);
    assert_true(fabs(out.corr_mm[1] - full) < 1e-9);
}

/* A rate or fade change while fading takes effect without a jump. */
static void test_param_change_no_jump(void **state)
{
    (void)state;
    abbe_lcnc_params_t p;
    abbe_lcnc_default_params(&p);
    p.fade_s = 1.0;
    setup_port(ABBE_LCNC_VARIANT_Q, &p, "paper");
    abbe_lcnc_input_t in;
    abbe_lcnc_output_t out;
    double prev[3] = {0, 0, 0};
    for (unsigned k = 0; k < 3600; k++) {
        if (k == 300) {
            p.fade_s = 0.05; /* faster fade mid-fade */
        }
        if (k == 600) {
            p.rate_mm_per_s[1] = 0.01; /* 10 nm per cycle */
        }
        if (k == 1200) {
            p.fade_s = 2.0;
        }
        input_at(&in, k);
        in.enable = k < 1500;
        abbe_lcnc_step(&port, &p, PERIOD_NS, &in, &out);
        for (unsigned j = 0; j < 3; j++) {
            double limit = (j == 1 && k >= 600) ? 10e-6 : 1e-3;
            if (fabs(out.corr_mm[j] - prev[j]) > limit + 1e-12) {
                fail_msg("cycle %u axis %u: correction moved %.9f mm", k, j, out.corr_mm[j] - prev[j]);
            }
            prev[j] = out.corr_mm[j];
        }
    }
    for (unsigned j = 0; j < 3; j++) {
        assert_true(out.corr_mm[j] == 0.0); /* 2.1 s after the disable, 2 s fade */
    }
}

/* NaN positions: held, then faded out after stale-s; counted. */
static void test_invalid_input(void **state)
{
    (void)state;
    abbe_lcnc_params_t p;
    abbe_lcnc_default_params(&p);
    p.fade_s = 0.01;
    p.stale_s = 0.005;
    p.rate_mm_per_s[0] = p.rate_mm_per_s[1] = p.rate_mm_per_s[2] = 100.0;
    setup_port(ABBE_LCNC_VARIANT_F32, &p, "paper");
    abbe_lcnc_input_t in;
    abbe_lcnc_output_t out;
    for (unsigned k = 0; k < 50; k++) {
        input_at(&in, 0);
        abbe_lcnc_step(&port, &p, PERIOD_NS, &in, &out);
    }
    double full = out.corr_mm[0];
    in.pos_mm[2] = strtod("nan", NULL);
    for (unsigned k = 0; k < 4; k++) {
        abbe_lcnc_step(&port, &p, PERIOD_NS, &in, &out);
        assert_true(out.flags & ABBE_FLAG_INPUT_INVALID);
        assert_true(out.corr_mm[0] == full); /* held */
    }
    for (unsigned k = 0; k < 30; k++) {
        abbe_lcnc_step(&port, &p, PERIOD_NS, &in, &out);
    }
    assert_true(out.flags & ABBE_FLAG_STALE);
    assert_true(out.corr_mm[0] == 0.0);
    assert_int_equal(out.stats.invalid_inputs, 34);
}

/* An axis fault fades that axis out, the others go on. */
static void test_axis_fault(void **state)
{
    (void)state;
    abbe_lcnc_params_t p;
    quick_params(&p);
    setup_port(ABBE_LCNC_VARIANT_Q, &p, "paper");
    abbe_lcnc_input_t in;
    abbe_lcnc_output_t out;
    input_at(&in, 0);
    for (unsigned k = 0; k < 50; k++) {
        abbe_lcnc_step(&port, &p, PERIOD_NS, &in, &out);
    }
    double full[3];
    memcpy(full, out.corr_mm, sizeof full);
    in.axis_fault[1] = 1;
    double prev = full[1];
    for (unsigned k = 0; k < 50; k++) {
        abbe_lcnc_step(&port, &p, PERIOD_NS, &in, &out);
        assert_true(fabs(out.corr_mm[1] - prev) <= fabs(full[1]) / 20.0 + 1e-9);
        prev = out.corr_mm[1];
    }
    assert_true(out.corr_mm[1] == 0.0);
    assert_true(out.flags & ABBE_FLAG_AXIS_FAULT);
    assert_true(fabs(out.corr_mm[0] - full[0]) < 1e-9 && fabs(out.corr_mm[2] - full[2]) < 1e-9);
    assert_int_equal(out.state, ABBE_COMP_ON);
    in.axis_fault[1] = 0;
    for (unsigned k = 0; k < 50; k++) {
        abbe_lcnc_step(&port, &p, PERIOD_NS, &in, &out);
    }
    assert_true(fabs(out.corr_mm[1] - full[1]) < 1e-9);
}

/* ---- backlash direction ---------------------------------------------------------- */

/* The port's direction with hysteresis drives the library's direction state:
 * compare the target with a direct library evaluation at the state the
 * documented rule gives. */
static void test_direction_deadband(void **state)
{
    (void)state;
    const abbe_golden_table_t *t = golden("full"); /* has backlash */
    abbe_lcnc_params_t p;
    abbe_lcnc_default_params(&p);
    for (unsigned j = 0; j < 3; j++) {
        p.warn_mm[j] = 1.0;
        p.limit_mm[j] = 2.0;
    }
    p.dir_deadband_mm = 0.002;
    p.lead_periods = 0.0; /* directions of the positions themselves */
    assert_int_equal(abbe_lcnc_init(&port, ABBE_LCNC_VARIANT_Q, &p, PERIOD_NS), ABBE_OK);
    assert_int_equal(abbe_lcnc_add_table(&port, aligned_blob(0, t), t->blob_size), ABBE_OK);
    abbe_model_t m;
    assert_int_equal(abbe_model_load(&m, blob_store[0], t->blob_size), ABBE_OK);

    /* Deadband 2 um. X moves 0 -> 3 um: + once beyond 2 um from the start;
     * back to 1 um (2 um from the furthest point, not beyond): still +; on to
     * 0.5 um: turns to -; then on down and standing: stays -. Compare the
     * target with a plain compensator fed the directions of that rule. */
    static const double x_um[] = {0, 1, 2, 3, 2.5, 2, 1.5, 1, 0.5, 0, -0.5, -1, -1.5, -1.5, -1.5};
    static const int8_t want_dir[] = {0, 0, 0, 1, 1, 1, 1, 1, -1, -1, -1, -1, -1, -1, -1};
    abbe_comp_t ref;
    abbe_comp_config_t cfg;
    assert_int_equal(abbe_lcnc_params_to_config(&p, PERIOD_NS, &cfg), ABBE_OK);
    assert_int_equal(abbe_comp_init(&ref, &cfg, &m), ABBE_OK);
    for (size_t k = 0; k < sizeof x_um / sizeof x_um[0]; k++) {
        abbe_lcnc_input_t in;
        abbe_lcnc_output_t out;
        memset(&in, 0, sizeof in);
        in.pos_mm[0] = 100.0 + x_um[k] * 1e-3;
        in.pos_mm[1] = 50.0;
        in.pos_mm[2] = -20.0;
        in.temp_c[0] = in.temp_c[1] = in.temp_c[2] = 21.0;
        abbe_lcnc_step(&port, &p, PERIOD_NS, &in, &out);
        abbe_comp_input_q_t ci;
        abbe_comp_output_t co;
        memset(&ci, 0, sizeof ci);
        for (unsigned j = 0; j < 3; j++) {
            ci.pos_nm[j] = mm_nm(in.pos_mm[j]);
            ci.temp_mdegc[j] = 21000;
        }
        ci.dir[0] = want_dir[k];
        ci.fresh = 1;
        assert_int_equal(abbe_comp_step_q(&ref, &ci, &co), ABBE_OK);
        for (unsigned j = 0; j < 3; j++) {
            if (mm_nm(out.target_mm[j]) != co.target_nm[j]) {
                fail_msg("step %zu axis %u: port target %d nm, library with dir %d: %d nm", k, j,
                         mm_nm(out.target_mm[j]), want_dir[k], co.target_nm[j]);
            }
        }
    }
}

/* The lead: the model is evaluated at p + lead * (p - p_previous); the first
 * period, and the first after an invalid input, at p. */
static void test_lead(void **state)
{
    (void)state;
    abbe_lcnc_params_t p;
    abbe_lcnc_default_params(&p);
    p.lead_periods = 2.0;
    p.stale_s = 1.0;
    setup_port(ABBE_LCNC_VARIANT_Q, &p, "paper");
    abbe_model_t m;
    assert_int_equal(abbe_model_load(&m, blob_store[0], golden("paper")->blob_size), ABBE_OK);
    int32_t prev[3] = {0, 0, 0};
    for (unsigned k = 0; k < 60; k++) {
        abbe_lcnc_input_t in;
        abbe_lcnc_output_t out;
        input_at(&in, 37 * k); /* big steps: the lead shows */
        if (k == 30) {
            in.pos_mm[0] = strtod("nan", NULL);
        }
        abbe_lcnc_step(&port, &p, PERIOD_NS, &in, &out);
        if (k == 30) {
            continue;
        }
        abbe_input_q_t ei;
        abbe_error_q_t eo;
        memset(&ei, 0, sizeof ei);
        for (unsigned j = 0; j < 3; j++) {
            int32_t now = mm_nm(in.pos_mm[j]);
            ei.pos_nm[j] = (k == 0 || k == 31) ? now : now + 2 * (now - prev[j]);
            prev[j] = now;
        }
        assert_int_equal(abbe_error_eval_q(&m, &ei, &eo), ABBE_OK);
        for (unsigned j = 0; j < 3; j++) {
            if (mm_nm(out.target_mm[j]) != -eo.error_nm[j]) {
                fail_msg("period %u axis %u: target %d nm, model ahead %d nm", k, j,
                         mm_nm(out.target_mm[j]), -eo.error_nm[j]);
            }
        }
    }
    /* out of range */
    abbe_comp_config_t c;
    p.lead_periods = -1.0;
    assert_int_equal(abbe_lcnc_params_to_config(&p, PERIOD_NS, &c), ABBE_E_ARG);
    p.lead_periods = 101.0;
    assert_int_equal(abbe_lcnc_params_to_config(&p, PERIOD_NS, &c), ABBE_E_ARG);
}

/* With a lead, a stop is not a reversal: decelerating to standstill, the
 * extrapolated position runs past the stop and comes back, but the backlash
 * direction follows the commanded motion (still +). Compare with a plain
 * compensator fed the lead positions and direction +. */
static void test_lead_stop_keeps_direction(void **state)
{
    (void)state;
    const abbe_golden_table_t *t = golden("full"); /* has backlash */
    abbe_lcnc_params_t p;
    abbe_lcnc_default_params(&p);
    for (unsigned j = 0; j < 3; j++) {
        p.warn_mm[j] = 1.0;
        p.limit_mm[j] = 2.0;
    }
    assert_int_equal(abbe_lcnc_init(&port, ABBE_LCNC_VARIANT_Q, &p, PERIOD_NS), ABBE_OK);
    assert_int_equal(abbe_lcnc_add_table(&port, aligned_blob(0, t), t->blob_size), ABBE_OK);
    abbe_model_t m;
    assert_int_equal(abbe_model_load(&m, blob_store[0], t->blob_size), ABBE_OK);
    abbe_comp_t ref;
    abbe_comp_config_t cfg;
    assert_int_equal(abbe_lcnc_params_to_config(&p, PERIOD_NS, &cfg), ABBE_OK);
    assert_int_equal(abbe_comp_init(&ref, &cfg, &m), ABBE_OK);
    /* X at 50 mm/s, braking at 2000 mm/s^2 to a stop, then standing */
    double x = 100.0, v = 0.05; /* mm per period */
    int32_t prev = 0;
    for (unsigned k = 0; k < 200; k++) {
        if (k >= 100) {
            v = v > 0.002 ? v - 0.002 : 0.0;
        }
        x += v;
        abbe_lcnc_input_t in;
        abbe_lcnc_output_t out;
        memset(&in, 0, sizeof in);
        in.pos_mm[0] = x;
        in.pos_mm[1] = 50.0;
        in.pos_mm[2] = -20.0;
        in.temp_c[0] = in.temp_c[1] = in.temp_c[2] = 20.0;
        abbe_lcnc_step(&port, &p, PERIOD_NS, &in, &out);
        abbe_comp_input_q_t ci;
        abbe_comp_output_t co;
        memset(&ci, 0, sizeof ci);
        int32_t now = mm_nm(x);
        ci.pos_nm[0] = k == 0 ? now : now + 2 * (now - prev);
        prev = now;
        ci.pos_nm[1] = mm_nm(50.0);
        ci.pos_nm[2] = mm_nm(-20.0);
        for (unsigned j = 0; j < 3; j++) {
            ci.temp_mdegc[j] = 20000;
        }
        ci.dir[0] = k == 0 ? 0 : 1;
        ci.fresh = 1;
        assert_int_equal(abbe_comp_step_q(&ref, &ci, &co), ABBE_OK);
        if (mm_nm(out.target_mm[0]) != co.target_nm[0]) {
            fail_msg("period %u: port %d nm, compensator moving + %d nm", k, mm_nm(out.target_mm[0]),
                     co.target_nm[0]);
        }
    }
}

/* ---- tables ------------------------------------------------------------------------- */

static void test_table_select(void **state)
{
    (void)state;
    abbe_lcnc_params_t p;
    abbe_lcnc_default_params(&p);
    p.rate_mm_per_s[0] = p.rate_mm_per_s[1] = p.rate_mm_per_s[2] = 0.5; /* 500 nm/cycle */
    p.fade_s = 0.01;
    for (unsigned j = 0; j < 3; j++) {
        p.warn_mm[j] = 1.0;
        p.limit_mm[j] = 2.0;
    }
    const abbe_golden_table_t *a = golden("paper"), *b = golden("negative");
    assert_int_equal(abbe_lcnc_init(&port, ABBE_LCNC_VARIANT_Q, &p, PERIOD_NS), ABBE_OK);
    assert_int_equal(abbe_lcnc_add_table(&port, aligned_blob(0, a), a->blob_size), ABBE_OK);
    assert_int_equal(abbe_lcnc_add_table(&port, aligned_blob(1, b), b->blob_size), ABBE_OK);
    assert_int_equal(abbe_lcnc_table_count(&port), 2);
    abbe_lcnc_input_t in;
    abbe_lcnc_output_t out;
    input_at(&in, 0);
    for (unsigned k = 0; k < 100; k++) {
        abbe_lcnc_step(&port, &p, PERIOD_NS, &in, &out);
    }
    assert_int_equal(out.table_active, 0);
    uint32_t crc0 = out.model_crc;
    assert_int_equal(crc0, abbe_lcnc_table_crc(&port, 0));
    double before[3];
    memcpy(before, out.corr_mm, sizeof before);
    in.table_select = 1;
    double prev[3];
    memcpy(prev, before, sizeof prev);
    abbe_lcnc_step(&port, &p, PERIOD_NS, &in, &out);
    assert_int_equal(out.table_active, 1); /* the swap takes effect in the step that sees it */
    assert_int_equal(out.model_crc, abbe_lcnc_table_crc(&port, 1));
    assert_true(out.flags & ABBE_FLAG_MODEL_SWAPPED);
    for (unsigned k = 0; k < 400; k++) {
        for (unsigned j = 0; j < 3; j++) {
            assert_true(fabs(out.corr_mm[j] - prev[j]) <= 500e-6 + 1e-12); /* ramps, no jump */
            prev[j] = out.corr_mm[j];
        }
        abbe_lcnc_step(&port, &p, PERIOD_NS, &in, &out);
    }
    int changed = 0;
    for (unsigned j = 0; j < 3; j++) {
        changed |= fabs(out.corr_mm[j] - before[j]) > 1e-6;
        assert_true(fabs(out.corr_mm[j] - out.target_mm[j]) < 1e-9);
    }
    assert_true(changed);
    /* an index beyond the tables: flagged, the running one stays */
    in.table_select = 3;
    abbe_lcnc_step(&port, &p, PERIOD_NS, &in, &out);
    assert_true(out.flags & ABBE_LCNC_FLAG_TABLE_SELECT);
    assert_int_equal(out.table_active, 1);
    in.table_select = -1;
    abbe_lcnc_step(&port, &p, PERIOD_NS, &in, &out);
    assert_true(out.flags & ABBE_LCNC_FLAG_TABLE_SELECT);
    assert_int_equal(out.table_active, 1);
}

static void test_bad_tables(void **state)
{
    (void)state;
    abbe_lcnc_params_t p;
    abbe_lcnc_default_params(&p);
    const abbe_golden_table_t *t = golden("paper");
    assert_int_equal(abbe_lcnc_init(&port, ABBE_LCNC_VARIANT_Q, &p, PERIOD_NS), ABBE_OK);
    uint8_t *b = (uint8_t *)blob_store[0];
    memcpy(b, t->blob, t->blob_size);
    b[300] ^= 1u;
    assert_int_equal(abbe_lcnc_add_table(&port, b, t->blob_size), ABBE_E_CRC);
    assert_int_equal(abbe_lcnc_add_table(&port, b, 10), ABBE_E_TRUNCATED);
    assert_int_equal(abbe_lcnc_table_count(&port), 0);
    b[300] ^= 1u;
    for (unsigned i = 0; i < ABBE_LCNC_MAX_TABLES; i++) {
        assert_int_equal(abbe_lcnc_add_table(&port, b, t->blob_size), ABBE_OK);
    }
    assert_int_equal(abbe_lcnc_add_table(&port, b, t->blob_size), ABBE_E_ARG); /* full */
}

static void test_read_file(void **state)
{
    (void)state;
    char why[160];
    size_t size = 0;
    assert_int_equal(abbe_lcnc_read_file(ABBE_EXAMPLE_MODEL, blob_store[0], sizeof blob_store[0],
                                         &size, why, sizeof why), 0);
    assert_int_equal(size, 1412);
    assert_int_equal(abbe_lcnc_read_file(ABBE_EXAMPLE_MODEL, blob_store[0], 1000, &size, why,
                                         sizeof why), -1);
    assert_string_equal(why, "larger than 1000 bytes");
    assert_int_equal(abbe_lcnc_read_file(ABBE_EXAMPLE_MODEL, blob_store[0], 1412, &size, why,
                                         sizeof why), 0);
    assert_int_equal(abbe_lcnc_read_file("/nonexistent/abbe/model.bin", blob_store[0], 100, &size,
                                         why, sizeof why), -1);
    assert_string_equal(why, "cannot open: No such file or directory");
    assert_int_equal(abbe_lcnc_read_file("/dev/null", blob_store[0], 100, &size, why, sizeof why), -1);
    assert_string_equal(why, "empty file");
}

/* ---- five-axis mode --------------------------------------------------------------- */

/* The golden five-axis table `name` in slot `slot`. */
static const abbe_golden_five_table_t *golden_five(const char *name, unsigned slot, const void **blob)
{
    for (uint32_t i = 0; i < abbe_golden_five_table_count; i++) {
        const abbe_golden_five_table_t *t = &abbe_golden_five_tables[i];
        if (strcmp(t->name, name) == 0) {
            assert_true(t->blob_size <= sizeof blob_store[slot]);
            memcpy(blob_store[slot], t->blob, t->blob_size);
            *blob = blob_store[slot];
            return t;
        }
    }
    fail_msg("golden five-axis table %s missing", name);
    return NULL;
}

/* The joint-frame correction v as a world offset under trt kinematics, written
 * here with libm: e = (R_tilt(t) Rz(c))^T v. */
static void expect_workpiece(uint32_t kind, double t_deg, double c_deg, const double v[3], double e[3])
{
    const double pi = 3.14159265358979323846;
    double t = t_deg * pi / 180.0, c = c_deg * pi / 180.0;
    double rt[3][3], rz[3][3] = {{cos(c), -sin(c), 0.0}, {sin(c), cos(c), 0.0}, {0.0, 0.0, 1.0}};
    if (kind >= ABBE_KIN_XYZBC_HH) {
        /* format 1.4's kinds, from the modules' inverse kinematics (kinds_sim.py's reading):
         * 5axiskins world = joints + f(B, C): e = v; maxkins j = Rz(-C) P - h(B): e = Rz(C) v;
         * xyzab_tdr_kins j = Ry(B)^T Rx(A)^T p + ...: e = Rx(A) Ry(B) v (A = t, B = c here) */
        double m[3][3] = {{1.0, 0.0, 0.0}, {0.0, 1.0, 0.0}, {0.0, 0.0, 1.0}};
        if (kind == ABBE_KIN_XYZBC_HT) {
            memcpy(m, rz, sizeof m);
        } else if (kind == ABBE_KIN_XYZAB_TDR) {
            double rx[3][3] = {{1.0, 0.0, 0.0}, {0.0, cos(t), -sin(t)}, {0.0, sin(t), cos(t)}};
            double ry[3][3] = {{cos(c), 0.0, sin(c)}, {0.0, 1.0, 0.0}, {-sin(c), 0.0, cos(c)}};
            for (unsigned i = 0; i < 3; i++) {
                for (unsigned j = 0; j < 3; j++) {
                    m[i][j] = 0.0;
                    for (unsigned k = 0; k < 3; k++) {
                        m[i][j] += rx[i][k] * ry[k][j];
                    }
                }
            }
        }
        for (unsigned i = 0; i < 3; i++) {
            e[i] = m[i][0] * v[0] + m[i][1] * v[1] + m[i][2] * v[2];
        }
        return;
    }
    if (kind == ABBE_KIN_XYZAC_TRT) {
        double m[3][3] = {{1.0, 0.0, 0.0}, {0.0, cos(t), -sin(t)}, {0.0, sin(t), cos(t)}};
        memcpy(rt, m, sizeof rt);
    } else {
        double m[3][3] = {{cos(t), 0.0, sin(t)}, {0.0, 1.0, 0.0}, {-sin(t), 0.0, cos(t)}};
        memcpy(rt, m, sizeof rt);
    }
    for (unsigned i = 0; i < 3; i++) {
        e[i] = 0.0;
        for (unsigned j = 0; j < 3; j++) {
            double r = 0.0; /* (rt rz)[j][i] */
            for (unsigned k = 0; k < 3; k++) {
                r += rt[j][k] * rz[k][i];
            }
            e[i] += r * v[j];
        }
    }
}

/* Five-axis tables: the correction is the model's (golden vectors), in the
 * joint frame under identity kinematics and turned into workpiece coordinates
 * under the trt kinematics; an unknown kinstype fades it out; disabled, the
 * offsets end exactly at zero; a 3-axis table does not mix in. */
static void five_axis_case(const char *name, abbe_lcnc_variant_t variant)
{
    abbe_lcnc_params_t p;
    abbe_lcnc_default_params(&p);
    p.lead_periods = 0.0;
    p.fade_s = 0.001;
    for (unsigned j = 0; j < 3; j++) {
        p.warn_mm[j] = 1.0;
        p.limit_mm[j] = 2.0;
        p.rate_mm_per_s[j] = 100.0;
    }
    const void *blob;
    const abbe_golden_five_table_t *t = golden_five(name, 0, &blob);
    assert_int_equal(abbe_lcnc_init(&port, variant, &p, PERIOD_NS), ABBE_OK);
    assert_int_equal(abbe_lcnc_blob_kind(blob, t->blob_size), t->kind);
    assert_int_equal(abbe_lcnc_add_table(&port, blob, t->blob_size), ABBE_OK);
    assert_int_equal(abbe_lcnc_kind(&port), t->kind);
    const abbe_golden_table_t *three = golden("paper");
    assert_int_equal(abbe_lcnc_blob_kind(aligned_blob(1, three), three->blob_size), ABBE_KIN_NONE);
    assert_int_equal(abbe_lcnc_add_table(&port, blob_store[1], three->blob_size), ABBE_E_ARG);
    assert_int_equal(abbe_lcnc_table_count(&port), 1);

    double worst_pos = 0.0, worst_rot = 0.0, worst_frame = 0.0;
    for (uint32_t i = t->first_point; i < t->first_point + 12u; i++) {
        const abbe_golden_five_point_t *g = &abbe_golden_five_points[i];
        abbe_lcnc_input_t in;
        abbe_lcnc_output_t out;
        memset(&in, 0, sizeof in);
        for (unsigned j = 0; j < 3; j++) {
            in.pos_mm[j] = (double)g->pos_nm[j] / 1e6;
            in.temp_c[j] = 20.0;
        }
        in.angle_deg[0] = (double)g->angle_udeg[0] / 1e6;
        in.angle_deg[1] = (double)g->angle_udeg[1] / 1e6;
        in.enable = in.homed = in.machine_on = 1;
        in.kinstype = (double)p.kins_identity;
        for (unsigned k = 0; k < 40; k++) {
            abbe_lcnc_step(&port, &p, PERIOD_NS, &in, &out);
        }
        assert_int_equal(out.frame, ABBE_LCNC_FRAME_JOINTS);
        const int32_t *want_pm = variant == ABBE_LCNC_VARIANT_Q ? g->expect_q_pm : g->expect_f32_pm;
        const int32_t *want_prad = variant == ABBE_LCNC_VARIANT_Q ? g->expect_q_prad : g->expect_f32_prad;
        for (unsigned j = 0; j < 3; j++) {
            /* correction = -error; the port rounds to 1 nm, the orientation to 1 nrad */
            double d = fabs(out.target_mm[j] * 1e9 + (double)want_pm[j]);
            worst_pos = d > worst_pos ? d : worst_pos;
            assert_true(d <= ABBE_GOLDEN_FIVE_TOL_PM + 500.0 + (variant == ABBE_LCNC_VARIANT_F32 ? 4000.0 : 0.0));
            double r = fabs(out.orient_urad[j] * 1e6 - (double)want_prad[j]);
            worst_rot = r > worst_rot ? r : worst_rot;
            assert_true(r <= ABBE_GOLDEN_FIVE_TOL_PRAD + 500.0 + (variant == ABBE_LCNC_VARIANT_F32 ? 2000.0 : 0.0));
            assert_true(fabs(out.corr_mm[j] - out.target_mm[j]) < 1e-12);
            assert_true(fabs(out.offset_mm[j] - out.corr_mm[j]) < 1e-12); /* identity: world = joints */
        }
        /* trt kinematics: the same correction as a workpiece-frame offset */
        in.kinstype = (double)p.kins_tcp;
        for (unsigned k = 0; k < 40; k++) {
            abbe_lcnc_step(&port, &p, PERIOD_NS, &in, &out);
        }
        assert_int_equal(out.frame, ABBE_LCNC_FRAME_WORKPIECE);
        double e[3];
        expect_workpiece(t->kind, in.angle_deg[0], in.angle_deg[1], out.corr_mm, e);
        for (unsigned j = 0; j < 3; j++) {
            double d = fabs(out.offset_mm[j] - e[j]);
            worst_frame = d > worst_frame ? d : worst_frame;
            assert_true(d <= 1.0e-6); /* 1 nm: the port's rounding */
        }
    }
    print_message("five-axis %s %s: |target + error| <= %.0f pm, orientation <= %.0f prad, "
                  "workpiece frame <= %.2g mm\n", name, variant == ABBE_LCNC_VARIANT_Q ? "q" : "f32",
                  worst_pos, worst_rot, worst_frame);

    /* a kinstype naming neither kinematics: flagged, held, then faded out */
    abbe_lcnc_input_t in;
    abbe_lcnc_output_t out;
    memset(&in, 0, sizeof in);
    in.pos_mm[0] = 50.0;
    in.angle_deg[0] = 30.0;
    in.angle_deg[1] = 120.0;
    in.enable = in.homed = in.machine_on = 1;
    in.kinstype = (double)p.kins_tcp;
    for (unsigned k = 0; k < 40; k++) {
        abbe_lcnc_step(&port, &p, PERIOD_NS, &in, &out);
    }
    double norm = fabs(out.corr_mm[0]) + fabs(out.corr_mm[1]) + fabs(out.corr_mm[2]);
    assert_true(norm > 1e-4); /* the golden tables' errors are tens of um */
    in.kinstype = 7.0;
    abbe_lcnc_step(&port, &p, PERIOD_NS, &in, &out);
    assert_true(out.flags & ABBE_LCNC_FLAG_KINS);
    assert_int_equal(out.frame, ABBE_LCNC_FRAME_UNKNOWN);
    for (unsigned k = 0; k < 100; k++) {
        abbe_lcnc_step(&port, &p, PERIOD_NS, &in, &out);
    }
    for (unsigned j = 0; j < 3; j++) {
        assert_true(out.corr_mm[j] == 0.0 && out.offset_mm[j] == 0.0);
    }
    /* back to a known kinematics: the correction returns; then disabled: exactly zero */
    in.kinstype = (double)p.kins_tcp;
    for (unsigned k = 0; k < 100; k++) {
        abbe_lcnc_step(&port, &p, PERIOD_NS, &in, &out);
    }
    norm = fabs(out.offset_mm[0]) + fabs(out.offset_mm[1]) + fabs(out.offset_mm[2]);
    assert_true(norm > 1e-4);
    in.enable = 0;
    for (unsigned k = 0; k < 100; k++) {
        abbe_lcnc_step(&port, &p, PERIOD_NS, &in, &out);
    }
    for (unsigned j = 0; j < 3; j++) {
        assert_true(out.corr_mm[j] == 0.0 && out.offset_mm[j] == 0.0);
    }
    assert_int_equal(out.state, ABBE_COMP_OFF);
    /* kins_identity == kins_tcp is a configuration error */
    abbe_comp_config_t c;
    p.kins_tcp = p.kins_identity;
    assert_int_equal(abbe_lcnc_params_to_config(&p, PERIOD_NS, &c), ABBE_E_ARG);
}

static void test_five_axis_ac_q(void **state)
{
    (void)state;
    five_axis_case("ac_full", ABBE_LCNC_VARIANT_Q);
}

static void test_five_axis_bc_q(void **state)
{
    (void)state;
    five_axis_case("bc_motions", ABBE_LCNC_VARIANT_Q);
}

static void test_five_axis_ac_f32(void **state)
{
    (void)state;
    five_axis_case("ac_location", ABBE_LCNC_VARIANT_F32);
}

/* format 1.4's kinds (issue 39): the same checks, each module's world frame */
static void test_five_axis_kinds_q(void **state)
{
    (void)state;
#if defined(ABBE_NO_FIVE_KINDS)
    skip(); /* a trunnion-only library */
#endif
    five_axis_case("hh_5axiskins", ABBE_LCNC_VARIANT_Q);
    five_axis_case("ht_maxkins", ABBE_LCNC_VARIANT_Q);
    five_axis_case("tdr_xyzab", ABBE_LCNC_VARIANT_Q);
}

static void test_five_axis_kinds_f32(void **state)
{
    (void)state;
#if defined(ABBE_NO_FIVE_KINDS)
    skip(); /* a trunnion-only library */
#endif
    five_axis_case("hh_5axiskins", ABBE_LCNC_VARIANT_F32);
    five_axis_case("ht_maxkins", ABBE_LCNC_VARIANT_F32);
    five_axis_case("tdr_xyzab", ABBE_LCNC_VARIANT_F32);
}

/* ---- the thermal block (format 1.3) ------------------------------------------- */

/* The golden thermal table, its 17 inputs on th_in (sampled every 0.1 s), a
 * fixed position: every sample's channels equal a standalone runtime fed the
 * same values; input 3 open for 1 s: flags, hold, fade out, back; the target
 * never jumps. */
static void thermal_case(abbe_lcnc_variant_t v)
{
    static uint32_t store[ABBE_LCNC_TABLE_MAX_BYTES / 4];
    abbe_lcnc_params_t p;
    quick_params(&p);
    p.thermal_sample_s = 0.1;
    p.fade_s = 0.5;
    p.warn_mm[0] = p.warn_mm[1] = p.warn_mm[2] = 5.0;
    p.limit_mm[0] = p.limit_mm[1] = p.limit_mm[2] = 10.0;
    memcpy(store, abbe_golden_thermal_blob, abbe_golden_thermal_blob_size);
    assert_int_equal(abbe_lcnc_init(&port, v, &p, PERIOD_NS), ABBE_OK);
    assert_int_equal(abbe_lcnc_add_table(&port, store, abbe_golden_thermal_blob_size), ABBE_OK);
    abbe_model_t m;
    abbe_thermal_model_t tm;
    abbe_thermal_state_t sh;
    assert_int_equal(abbe_thermal_load(&m, &tm, abbe_golden_thermal_blob, abbe_golden_thermal_blob_size), ABBE_OK);
    if (v == ABBE_LCNC_VARIANT_F32) {
        assert_int_equal(abbe_thermal_init_f32(&sh, &tm, 0.001f), ABBE_OK);
    } else {
        assert_int_equal(abbe_thermal_init_q(&sh, &tm, 1000u), ABBE_OK);
    }
    abbe_lcnc_input_t in;
    abbe_lcnc_output_t out;
    double prev[3] = {0, 0, 0}, step_clean = 0.0, step_fault = 0.0, ymax = 0.0;
    uint32_t n = 0;
    const unsigned periods = 100u; /* 0.1 s at 1 ms */
    for (unsigned k = 0; k < 90000u; k++) { /* the table's fade is 30 s: out, then in again */
        memset(&in, 0, sizeof in);
        in.pos_mm[0] = 250.0;
        in.pos_mm[1] = -200.0;
        in.pos_mm[2] = -150.0;
        in.temp_c[0] = in.temp_c[1] = in.temp_c[2] = 20.0;
        in.enable = in.homed = in.machine_on = 1;
        const abbe_golden_thermal_sample_t *s = &abbe_golden_thermal_samples[k / periods < abbe_golden_thermal_sample_count ? k / periods : abbe_golden_thermal_sample_count - 1u]; /* no wrap: its jump would be a STEP fault */
        int fault = k >= 20000u && k < 21000u;
        uint32_t valid = 0;
        for (unsigned i = 0; i < ABBE_LCNC_TH_INPUTS; i++) {
            in.th_in[i] = i == 16u ? (double)s->x_milli[i] : (double)s->x_milli[i] / 1000.0;
            in.th_fault[i] = (uint8_t)(fault && i == 3u);
            valid |= in.th_fault[i] ? 0u : 1u << i;
        }
        if (k % periods == 0u) { /* the port samples now: so does the shadow */
            if (v == ABBE_LCNC_VARIANT_F32) {
                float x[17];
                for (unsigned i = 0; i < 17u; i++) {
                    x[i] = (float)in.th_in[i];
                }
                assert_int_equal(abbe_thermal_update_f32(&sh, x, valid, 0.1f), ABBE_OK);
            } else {
                assert_int_equal(abbe_thermal_update_q(&sh, s->x_milli, valid, 100u), ABBE_OK);
            }
            n++;
        }
        abbe_lcnc_step(&port, &p, PERIOD_NS, &in, &out);
        if (v == ABBE_LCNC_VARIANT_F32) {
            float e[3] = {0, 0, 0};
            abbe_thermal_apply_f32(&sh, e);
            float y[5];
            abbe_thermal_channels_f32(&sh, y);
            for (unsigned c = 0; c < 5u; c++) {
                assert_true(fabs(out.th_channel[c] - (double)y[c]) <= 1e-9);
                ymax = fabs(out.th_channel[c]) > ymax ? fabs(out.th_channel[c]) : ymax;
            }
        } else {
            int32_t e[3] = {0, 0, 0};
            abbe_thermal_apply_q(&sh, e);
            int32_t y[5];
            abbe_thermal_channels_q(&sh, y);
            for (unsigned c = 0; c < 5u; c++) {
                assert_true(fabs(out.th_channel[c] - (double)y[c] / 1000.0) <= 1e-9);
                ymax = fabs(out.th_channel[c]) > ymax ? fabs(out.th_channel[c]) : ymax;
            }
        }
        assert_int_equal(out.th_flags, abbe_thermal_flags(&sh));
        assert_int_equal(out.th_samples, n);
        if (fault) {
            assert_true(out.th_flags & ABBE_THERMAL_F_OPEN);
            assert_true(out.th_flags & ABBE_THERMAL_F_HOLD);
            assert_int_equal(out.th_input_faults, 1u << 3);
        }
        for (unsigned j = 0; j < 3u; j++) {
            double d = fabs(out.target_mm[j] - prev[j]) * 1e6; /* nm */
            if (k > 1000u && k < 20000u) {
                step_clean = d > step_clean ? d : step_clean;
            } else if (k >= 20000u) {
                step_fault = d > step_fault ? d : step_fault;
            }
            prev[j] = out.target_mm[j];
        }
    }
    assert_int_equal(out.th_flags & (ABBE_THERMAL_F_FAULTS | ABBE_THERMAL_F_HOLD | ABBE_THERMAL_F_FADING), 0u);
    /* a fade step moves a channel by |y| x 1 ms / 30 s (the table's fade time) */
    double bound = step_clean + 5.0 * ymax * 1000.0 * 0.001 / 30.0 + 2.0;
    print_message("LinuxCNC thermal (%s): largest target step per period %.0f nm clean, %.0f nm through the fault "
                  "(bound %.0f)\n", v == ABBE_LCNC_VARIANT_F32 ? "f32" : "q", step_clean, step_fault, bound);
    assert_true(step_fault <= bound);
}

static void test_thermal_q(void **state)
{
    (void)state;
    thermal_case(ABBE_LCNC_VARIANT_Q);
}

static void test_thermal_f32(void **state)
{
    (void)state;
    thermal_case(ABBE_LCNC_VARIANT_F32);
}

/* A stuck sensor: the golden table with input ABBE_STUCK_INPUT's stuck check
 * on (2 min, 0.02 K), the th-in pins sampled every 1 s; the input ramps, then
 * repeats one value for 180 s, then ramps again. The th.flags pin shows
 * ABBE_THERMAL_F_STUCK (with HOLD, th.input-faults naming the input) exactly
 * 120 s after the last change; the target fades the thermal part out with no
 * step larger than a fade step, and everything clears when the reading moves
 * again. Every period equals a standalone runtime fed the same values. */
#define STUCK_HOLD_FROM 40u  /* samples (1 s apart) */
#define STUCK_HOLD_TO 220u
#define STUCK_SAMPLES 270u

static void stuck_case(abbe_lcnc_variant_t v)
{
    static uint32_t store[ABBE_LCNC_TABLE_MAX_BYTES / 4];
    size_t size = abbe_stuck_blob((uint8_t *)store, sizeof store);
    assert_true(size > 0u);
    abbe_lcnc_params_t p;
    quick_params(&p);
    p.thermal_sample_s = 1.0;
    p.fade_s = 0.5;
    p.warn_mm[0] = p.warn_mm[1] = p.warn_mm[2] = 5.0;
    p.limit_mm[0] = p.limit_mm[1] = p.limit_mm[2] = 10.0;
    assert_int_equal(abbe_lcnc_init(&port, v, &p, PERIOD_NS), ABBE_OK);
    assert_int_equal(abbe_lcnc_add_table(&port, store, size), ABBE_OK);
    abbe_model_t m;
    abbe_thermal_model_t tm;
    abbe_thermal_state_t sh;
    assert_int_equal(abbe_thermal_load(&m, &tm, store, size), ABBE_OK);
    if (v == ABBE_LCNC_VARIANT_F32) {
        assert_int_equal(abbe_thermal_init_f32(&sh, &tm, 0.001f), ABBE_OK);
    } else {
        assert_int_equal(abbe_thermal_init_q(&sh, &tm, 1000u), ABBE_OK);
    }
    uint32_t reads = 0; /* channels that read the stuck input */
    for (unsigned c = 0; c < tm.n_channels; c++) {
        reads |= ((tm.channel_inputs[c] >> ABBE_STUCK_INPUT) & 1u) << c;
    }
    assert_true(reads != 0u);
    const int32_t base = abbe_golden_thermal_samples[0].x_milli[ABBE_STUCK_INPUT];
    const unsigned periods = 1000u; /* 1 s at 1 ms */
    abbe_lcnc_input_t in;
    abbe_lcnc_output_t out;
    double prev[3] = {0, 0, 0}, step_clean = 0.0, step_fade = 0.0, step_between = 0.0, ymax = 0.0;
    uint32_t k_flag = 0, k_clear = 0, n = 0;
    for (uint32_t k = 0; k < STUCK_SAMPLES * periods; k++) {
        memset(&in, 0, sizeof in);
        in.pos_mm[0] = 250.0;
        in.pos_mm[1] = -200.0;
        in.pos_mm[2] = -150.0;
        in.temp_c[0] = in.temp_c[1] = in.temp_c[2] = 20.0;
        in.enable = in.homed = in.machine_on = 1;
        uint32_t i_s = k / periods;
        const abbe_golden_thermal_sample_t *s = &abbe_golden_thermal_samples[i_s < abbe_golden_thermal_sample_count ? i_s : abbe_golden_thermal_sample_count - 1u];
        int32_t xm[17];
        memcpy(xm, s->x_milli, sizeof xm);
        xm[ABBE_STUCK_INPUT] = abbe_stuck_reading_milli(base, i_s, STUCK_HOLD_FROM, STUCK_HOLD_TO);
        for (unsigned i = 0; i < ABBE_LCNC_TH_INPUTS; i++) {
            in.th_in[i] = i == 16u ? (double)xm[i] : (double)xm[i] / 1000.0;
        }
        if (k % periods == 0u) { /* the port samples now: so does the shadow */
            if (v == ABBE_LCNC_VARIANT_F32) {
                float x[17];
                for (unsigned i = 0; i < 17u; i++) {
                    x[i] = (float)in.th_in[i];
                }
                assert_int_equal(abbe_thermal_update_f32(&sh, x, 0x1FFFFu, 1.0f), ABBE_OK);
            } else {
                assert_int_equal(abbe_thermal_update_q(&sh, xm, 0x1FFFFu, 1000u), ABBE_OK);
            }
            n++;
        }
        abbe_lcnc_step(&port, &p, PERIOD_NS, &in, &out);
        if (v == ABBE_LCNC_VARIANT_F32) {
            float e[3] = {0, 0, 0};
            abbe_thermal_apply_f32(&sh, e);
            float y[5];
            abbe_thermal_channels_f32(&sh, y);
            for (unsigned c = 0; c < 5u; c++) {
                assert_true(fabs(out.th_channel[c] - (double)y[c]) <= 1e-9);
                ymax = fabs(out.th_channel[c]) > ymax ? fabs(out.th_channel[c]) : ymax;
            }
        } else {
            int32_t e[3] = {0, 0, 0};
            abbe_thermal_apply_q(&sh, e);
            int32_t y[5];
            abbe_thermal_channels_q(&sh, y);
            for (unsigned c = 0; c < 5u; c++) {
                assert_true(fabs(out.th_channel[c] - (double)y[c] / 1000.0) <= 1e-9);
                ymax = fabs(out.th_channel[c]) > ymax ? fabs(out.th_channel[c]) : ymax;
            }
        }
        assert_int_equal(out.th_flags, abbe_thermal_flags(&sh));
        assert_int_equal(out.th_samples, n);
        double step = 0.0;
        for (unsigned j = 0; j < 3u; j++) {
            double d = fabs(out.target_mm[j] - prev[j]) * 1e6; /* nm */
            step = d > step ? d : step;
            prev[j] = out.target_mm[j];
        }
        if (k > 1000u && k < STUCK_HOLD_FROM * periods) {
            step_clean = step > step_clean ? step : step_clean;
        }
        if ((out.th_flags & ABBE_THERMAL_F_STUCK) && k_flag == 0u) {
            k_flag = k;
        }
        if (k_flag != 0u) { /* the fade-out, the hold, the catch-up and fade-in */
            step_fade = step > step_fade ? step : step_fade;
            if (k % periods != 0u) { /* between samples only the fades move it */
                step_between = step > step_between ? step : step_between;
            }
        }
        if (k_flag != 0u && k_clear == 0u) {
            if (!(out.th_flags & ABBE_THERMAL_F_STUCK)) {
                k_clear = k;
            } else {
                assert_true(out.th_flags & ABBE_THERMAL_F_HOLD);
                assert_int_equal(out.th_input_faults, 1u << ABBE_STUCK_INPUT);
            }
        }
        if (k > 31000u && k_flag == 0u) { /* faded in (the table's 30 s), still moving or not yet stuck */
            assert_int_equal(out.th_flags & (ABBE_THERMAL_F_FAULTS | ABBE_THERMAL_F_HOLD | ABBE_THERMAL_F_FADING), 0u);
        }
        if (k_flag != 0u && k == k_flag + 30100u) { /* the table's fade (30 s, in whole weight steps) is over */
            for (unsigned c = 0; c < tm.n_channels; c++) {
                if (v == ABBE_LCNC_VARIANT_F32) {
                    assert_int_equal(sh.w[c] == 0.0f, (reads >> c) & 1u);
                } else {
                    assert_int_equal(sh.wq24[c] == 0u, (reads >> c) & 1u);
                }
            }
        }
    }
    assert_true(k_flag != 0u);
    /* the last change at sample STUCK_HOLD_FROM - 1; cleared by the first sample that moves */
    uint32_t flag_ms = k_flag - (STUCK_HOLD_FROM - 1u) * periods;
    assert_int_equal(k_clear, STUCK_HOLD_TO * periods);
    assert_int_equal(out.th_flags & (ABBE_THERMAL_F_FAULTS | ABBE_THERMAL_F_HOLD | ABBE_THERMAL_F_FADING), 0u);
    assert_true(abbe_thermal_events(&port.th) & ABBE_THERMAL_F_STUCK);
    double fade_step = 5.0 * ymax * 1000.0 * 0.001 / 30.0 + 2.0; /* every channel's, 1 ms of 30 s */
    double bound = step_clean + fade_step;
    print_message("LinuxCNC stuck sensor (%s): th.flags STUCK %u ms after the last change; largest target step per "
                  "period %.1f nm clean, %.1f nm from the flag through the fade-out and back (bound %.1f), "
                  "%.2f nm between samples (bound %.2f)\n",
                  v == ABBE_LCNC_VARIANT_F32 ? "f32" : "q", flag_ms, step_clean, step_fade, bound, step_between,
                  fade_step);
    assert_int_equal(flag_ms, 60000u * ABBE_STUCK_MIN);
    assert_true(step_fade <= bound);
    assert_true(step_between <= fade_step);
}

static void test_stuck_q(void **state)
{
    (void)state;
    stuck_case(ABBE_LCNC_VARIANT_Q);
}

static void test_stuck_f32(void **state)
{
    (void)state;
    stuck_case(ABBE_LCNC_VARIANT_F32);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_params_convert),
        cmocka_unit_test(test_thermal_q),
        cmocka_unit_test(test_thermal_f32),
        cmocka_unit_test(test_stuck_q),
        cmocka_unit_test(test_stuck_f32),
        cmocka_unit_test(test_params_rejected),
        cmocka_unit_test(test_runtime_bad_param),
        cmocka_unit_test(test_register_after_motion_q),
        cmocka_unit_test(test_register_before_motion_q),
        cmocka_unit_test(test_register_after_motion_f32),
        cmocka_unit_test(test_homed_low_gives_zero),
        cmocka_unit_test(test_fault_and_reset),
        cmocka_unit_test(test_param_change_no_jump),
        cmocka_unit_test(test_invalid_input),
        cmocka_unit_test(test_axis_fault),
        cmocka_unit_test(test_direction_deadband),
        cmocka_unit_test(test_lead),
        cmocka_unit_test(test_lead_stop_keeps_direction),
        cmocka_unit_test(test_table_select),
        cmocka_unit_test(test_bad_tables),
        cmocka_unit_test(test_read_file),
        cmocka_unit_test(test_five_axis_ac_q),
        cmocka_unit_test(test_five_axis_bc_q),
        cmocka_unit_test(test_five_axis_ac_f32),
        cmocka_unit_test(test_five_axis_kinds_q),
        cmocka_unit_test(test_five_axis_kinds_f32),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
