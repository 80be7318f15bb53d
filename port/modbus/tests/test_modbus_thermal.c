/* abbe-modbusd's thermal inputs (docs/modbus-registers.md, "Thermal inputs")
 * over Modbus TCP with a libmodbus client: the golden format 1.3 table
 * (tests/golden/golden_thermal.*, 16 temperatures + spindle speed, 5
 * channels) runs in the server; the client writes the 17 inputs, dt and the
 * sample trigger every 10th cycle, positions and IN_CYCLE every cycle, and
 * reads the thermal state and the outputs. Everything must equal, exactly, a
 * shadow compensator with its own thermal state fed the same values; then a
 * sensor fault (input 3 "no reading", then input 7 reading 300 degC): flags,
 * held channels, fade out without a jump, recovery. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <cmocka.h>

#include "abbe/modbus_port.h"
#include "golden_thermal.h"
#include "thermal_stuck.h"
#include "harness.h"

#define CYCLE_US 100000u
#define SAMPLE_EVERY 10u

static mbt_server_t srv;
static modbus_t *ctx;
static char model_path[256];
static abbe_comp_t shadow;
static abbe_model_t sh_model;
static abbe_thermal_model_t sh_tm;
static abbe_thermal_state_t sh_th;

static int server_start(const uint8_t *blob, size_t size)
{
    snprintf(model_path, sizeof model_path, "%s/abbe-mb-thermal-%ld.bin",
             getenv("TMPDIR") ? getenv("TMPDIR") : "/tmp", (long)getpid());
    FILE *f = fopen(model_path, "wb");
    if (f == NULL || fwrite(blob, 1, size, f) != size) {
        return -1;
    }
    fclose(f);
    const char *argv[] = {ABBE_MODBUSD, "--tcp", "127.0.0.1:0", "--model", model_path, "--enable",
                          "--cycle-us", "100000", NULL};
    if (mbt_server_start(&srv, NULL, argv, 20000) != 0) {
        return -1;
    }
    ctx = mbt_tcp_client(srv.port);
    /* the shadow: the server's defaults, the same table, enabled */
    abbe_mb_regs_config_t cfg;
    abbe_mb_regs_default_config(&cfg);
    if (abbe_thermal_load(&sh_model, &sh_tm, blob, size) != ABBE_OK ||
        abbe_comp_init(&shadow, &cfg.comp, &sh_model) != ABBE_OK || abbe_comp_enable(&shadow) != ABBE_OK ||
        abbe_thermal_init_q(&sh_th, &sh_tm, CYCLE_US) != ABBE_OK) {
        return -1;
    }
    return ctx != NULL ? 0 : -1;
}

static int group_setup(void **state)
{
    (void)state;
    return server_start(abbe_golden_thermal_blob, abbe_golden_thermal_blob_size);
}

/* the golden table with input ABBE_STUCK_INPUT's stuck check on (2 min, 0.02 K) */
static union { uint32_t align; uint8_t b[8192]; } stuck_blob;

static int stuck_group_setup(void **state)
{
    (void)state;
    size_t size = abbe_stuck_blob(stuck_blob.b, sizeof stuck_blob.b);
    return size > 0u ? server_start(stuck_blob.b, size) : -1;
}

static int group_teardown(void **state)
{
    (void)state;
    if (ctx != NULL) {
        modbus_close(ctx);
        modbus_free(ctx);
    }
    unlink(model_path);
    return mbt_server_stop(&srv) == 0 ? 0 : -1;
}

typedef struct { int32_t corr[3], err[3], y[5]; uint16_t flags; uint32_t faults; } answer_t;

/* The stuck test's reading of input ABBE_STUCK_INPUT, m degC (-1: the golden one). */
static int32_t stuck_milli = -1;

/* One sample: inputs as the registers carry them (0.01 degC; rpm), with faults;
 * past the golden record its last sample again (a wrap's jump would be a STEP fault) */
static void sample(uint32_t n, int no_reading, int hot)
{
    const abbe_golden_thermal_sample_t *s =
        &abbe_golden_thermal_samples[n < abbe_golden_thermal_sample_count ? n : abbe_golden_thermal_sample_count - 1u];
    uint16_t w[ABBE_MB_TIN_COUNT];
    int32_t x[17];
    uint32_t valid = 0;
    for (unsigned k = 0; k < 17u; k++) {
        int32_t v = k == 16u ? s->x_milli[k] : s->x_milli[k] / 10;
        if (k == ABBE_STUCK_INPUT && stuck_milli >= 0) {
            v = stuck_milli / 10;
        }
        if (k == 7u && hot) {
            v = 30000; /* 300 degC: a short, beyond the input's valid range */
        }
        x[k] = k == 16u ? v : 10 * v;
        if ((int)k == no_reading) {
            v = ABBE_MB_TEMP_NO_READING;
        } else {
            valid |= 1u << k;
        }
        w[k] = (uint16_t)(v & 0xFFFF);
    }
    w[17] = 0;
    mbt_put32(&w[18], SAMPLE_EVERY * CYCLE_US / 1000u, ABBE_MB_WORD_ORDER_HIGH_FIRST);
    w[20] = (uint16_t)n;
    assert_int_equal(modbus_write_registers(ctx, ABBE_MB_REG_TIN_BASE, ABBE_MB_TIN_COUNT, w), ABBE_MB_TIN_COUNT);
    assert_int_equal(abbe_thermal_update_q(&sh_th, x, valid, SAMPLE_EVERY * CYCLE_US / 1000u), ABBE_OK);
}

static answer_t cycle(uint16_t k)
{
    uint16_t w[ABBE_MB_IN_COUNT];
    memset(w, 0, sizeof w);
    int32_t pos[3] = {250000000, -300000000, -100000000};
    for (unsigned j = 0; j < 3; j++) {
        mbt_put32(&w[2u * j], (uint32_t)pos[j], ABBE_MB_WORD_ORDER_HIGH_FIRST);
        w[9u + j] = 2000;
    }
    w[13] = k;
    assert_int_equal(modbus_write_registers(ctx, ABBE_MB_REG_IN_BASE, ABBE_MB_IN_COUNT, w), ABBE_MB_IN_COUNT);
    answer_t a;
    uint16_t o[ABBE_MB_OUT_COUNT], t[ABBE_MB_TOUT_COUNT];
    assert_int_equal(modbus_read_registers(ctx, ABBE_MB_REG_OUT_BASE, ABBE_MB_OUT_COUNT, o), ABBE_MB_OUT_COUNT);
    assert_int_equal(modbus_read_registers(ctx, ABBE_MB_REG_TOUT_BASE, ABBE_MB_TOUT_COUNT, t), ABBE_MB_TOUT_COUNT);
    for (unsigned j = 0; j < 3; j++) {
        a.corr[j] = (int32_t)mbt_get32(&o[2u * j], 0);
        a.err[j] = (int32_t)mbt_get32(&o[6u + 2u * j], 0);
    }
    for (unsigned c = 0; c < 5; c++) {
        a.y[c] = (int32_t)mbt_get32(&t[6u + 2u * c], 0);
    }
    a.flags = t[0];
    a.faults = mbt_get32(&t[2], 0);
    assert_int_equal(t[1], (17 << 8) | 5);
    /* the shadow */
    abbe_comp_input_q_t in;
    memset(&in, 0, sizeof in);
    for (unsigned j = 0; j < 3; j++) {
        in.pos_nm[j] = pos[j];
        in.temp_mdegc[j] = 20000;
    }
    in.fresh = 1;
    abbe_comp_output_t out;
    assert_int_equal(abbe_comp_step_thermal_q(&shadow, &sh_th, &in, &out), ABBE_OK);
    int32_t y[5];
    abbe_thermal_channels_q(&sh_th, y);
    for (unsigned j = 0; j < 3; j++) {
        assert_int_equal(a.corr[j], out.corr_nm[j]);
        assert_int_equal(a.err[j], -out.target_nm[j]);
    }
    for (unsigned c = 0; c < 5; c++) {
        assert_int_equal(a.y[c], y[c]);
    }
    assert_int_equal(a.flags, (uint16_t)abbe_thermal_flags(&sh_th));
    return a;
}

static void test_thermal_inputs_and_faults(void **state)
{
    (void)state;
    uint32_t n = 0;
    uint16_t k = 0;
    answer_t a;
    int32_t prev_err[3] = {0, 0, 0}, step_clean = 0, step_fault = 0;
    for (; k < 600u; k++) { /* 60 s: fade in (30 s) and follow */
        if (k % SAMPLE_EVERY == 0u) {
            sample(n++, -1, 0);
        }
        a = cycle(k);
        for (unsigned j = 0; j < 3; j++) {
            int32_t d = abs(a.err[j] - prev_err[j]);
            step_clean = k > 400u && d > step_clean ? d : step_clean;
            prev_err[j] = a.err[j];
        }
    }
    assert_int_equal(a.flags & (ABBE_THERMAL_F_FAULTS | ABBE_THERMAL_F_HOLD | ABBE_THERMAL_F_FADING), 0);
    assert_true(a.y[0] != 0);
    int32_t y_before[5];
    memcpy(y_before, a.y, sizeof y_before);
    /* input 3 without a reading for 5 s, then input 7 shorted for 5 s */
    for (unsigned i = 0; i < 100u; i++, k++) {
        if (k % SAMPLE_EVERY == 0u) {
            sample(n++, i < 50u ? 3 : -1, i >= 50u);
        }
        a = cycle(k);
        assert_true(a.flags & ABBE_THERMAL_F_HOLD);
        assert_true(a.flags & (i < 50u ? ABBE_THERMAL_F_OPEN : ABBE_THERMAL_F_RANGE));
        assert_int_equal(a.faults, i < 50u ? 1u << 3 : 1u << 7);
        for (unsigned j = 0; j < 3; j++) {
            int32_t d = abs(a.err[j] - prev_err[j]);
            step_fault = d > step_fault ? d : step_fault;
            prev_err[j] = a.err[j];
        }
    }
    for (unsigned i = 0; i < 800u; i++, k++) {
        if (k % SAMPLE_EVERY == 0u) {
            sample(n++, -1, 0);
        }
        a = cycle(k);
        for (unsigned j = 0; j < 3; j++) {
            int32_t d = abs(a.err[j] - prev_err[j]);
            step_fault = d > step_fault ? d : step_fault;
            prev_err[j] = a.err[j];
        }
    }
    assert_int_equal(a.flags & (ABBE_THERMAL_F_FAULTS | ABBE_THERMAL_F_HOLD | ABBE_THERMAL_F_FADING), 0);
    int32_t bound = step_clean;
    for (unsigned c = 0; c < 5u; c++) {
        bound += abs(y_before[c]) / 300 + 1; /* one fade step (100 ms of 30 s) of each channel */
    }
    print_message("Modbus thermal: largest error step per cycle %d nm clean, %d nm through the faults (bound %d)\n",
                  step_clean, step_fault, bound);
    assert_true(step_fault <= bound);
    /* a reserved register must be 0; dt 0 is refused */
    assert_int_equal(modbus_write_register(ctx, ABBE_MB_REG_IN_TH_RESERVED, 1), -1);
    uint16_t zero[2] = {0, 0};
    assert_int_equal(modbus_write_registers(ctx, ABBE_MB_REG_IN_TH_DT_MS, 2, zero), -1);
}

/* A stuck sensor (a server running the golden table with input
 * ABBE_STUCK_INPUT's stuck check on: 2 min, 0.02 K): the input ramps, then
 * repeats one value for 240 s, then ramps again. TH_FLAGS (the port's thermal
 * status register) shows ABBE_THERMAL_F_STUCK exactly 120 s after the last
 * change, TH_INPUT_FAULTS the input, TH_EVENTS keeps it; the error fades out
 * with no step larger than a fade step and everything clears when the reading
 * moves again. Every cycle equals the shadow (cycle()). */
#define STUCK_HOLD_FROM 90u  /* samples (1 s apart) */
#define STUCK_HOLD_TO 330u
#define STUCK_SAMPLES 420u

static void test_stuck_sensor(void **state)
{
    (void)state;
    const int32_t base = abbe_golden_thermal_samples[0].x_milli[ABBE_STUCK_INPUT];
    uint32_t reads = 0; /* channels that read the stuck input */
    for (unsigned c = 0; c < sh_tm.n_channels; c++) {
        reads |= ((sh_tm.channel_inputs[c] >> ABBE_STUCK_INPUT) & 1u) << c;
    }
    assert_true(reads != 0u);
    int32_t prev[3] = {0, 0, 0}, step_clean = 0, step_fade = 0, step_between = 0, y_flag[5] = {0};
    uint32_t n = 0, k_flag = 0, k_clear = 0, k_last_change = 0;
    answer_t a;
    memset(&a, 0, sizeof a);
    for (uint32_t k = 0; n < STUCK_SAMPLES || k % SAMPLE_EVERY != 0u; k++) {
        if (k % SAMPLE_EVERY == 0u) {
            stuck_milli = abbe_stuck_reading_milli(base, n, STUCK_HOLD_FROM, STUCK_HOLD_TO);
            if (n == STUCK_HOLD_FROM - 1u) {
                k_last_change = k;
            }
            sample(n++, -1, 0);
        }
        a = cycle((uint16_t)k);
        int32_t step = 0;
        for (unsigned j = 0; j < 3; j++) {
            int32_t d = abs(a.err[j] - prev[j]);
            step = d > step ? d : step;
            prev[j] = a.err[j];
        }
        if (k > 400u && k < SAMPLE_EVERY * STUCK_HOLD_FROM) {
            step_clean = step > step_clean ? step : step_clean; /* faded in, the sensor moving */
        }
        if ((a.flags & ABBE_THERMAL_F_STUCK) && k_flag == 0u) {
            k_flag = k;
            memcpy(y_flag, a.y, sizeof y_flag);
        }
        if (k_flag != 0u) { /* the fade-out, the hold, the catch-up and fade-in */
            step_fade = step > step_fade ? step : step_fade;
            if (k % SAMPLE_EVERY != 0u) { /* between samples only the fades move it */
                step_between = step > step_between ? step : step_between;
            }
        }
        if (k_flag != 0u && k_clear == 0u) {
            if (!(a.flags & ABBE_THERMAL_F_STUCK)) {
                k_clear = k;
            } else {
                assert_true(a.flags & ABBE_THERMAL_F_HOLD);
                assert_int_equal(a.faults, 1u << ABBE_STUCK_INPUT);
            }
        }
        if (k > 400u && k_flag == 0u) {
            assert_int_equal(a.flags & (ABBE_THERMAL_F_FAULTS | ABBE_THERMAL_F_HOLD | ABBE_THERMAL_F_FADING), 0);
        }
        if (k_flag != 0u && k == k_flag + 301u) { /* the table's fade (30 s) is over: faded out */
            for (unsigned c = 0; c < sh_tm.n_channels; c++) {
                assert_int_equal(sh_th.wq24[c] == 0u, (reads >> c) & 1u);
            }
        }
    }
    stuck_milli = -1;
    assert_true(k_flag != 0u);
    assert_int_equal(k_clear, SAMPLE_EVERY * STUCK_HOLD_TO); /* the first sample that moves */
    assert_int_equal(a.flags & (ABBE_THERMAL_F_FAULTS | ABBE_THERMAL_F_HOLD | ABBE_THERMAL_F_FADING), 0);
    uint16_t ev[2];
    assert_int_equal(modbus_read_registers(ctx, ABBE_MB_REG_TH_EVENTS, 2, ev), 2);
    assert_true(mbt_get32(ev, 0) & ABBE_THERMAL_F_STUCK); /* sticky */
    uint32_t flag_ms = (k_flag - k_last_change) * (CYCLE_US / 1000u);
    int32_t fade_step = 0;
    for (unsigned c = 0; c < 5u; c++) {
        fade_step += abs(y_flag[c]) / 300 + 1; /* one fade step (100 ms of 30 s) of each channel */
    }
    int32_t bound = step_clean + fade_step;
    print_message("Modbus stuck sensor: TH_FLAGS 0x%02X %u ms after the last change; largest error step per cycle "
                  "%d nm clean, %d nm from the flag through the fade-out and back (bound %d), %d nm between samples "
                  "(bound %d); cleared when it moved\n",
                  (unsigned)ABBE_THERMAL_F_STUCK, flag_ms, step_clean, step_fade, bound, step_between, fade_step);
    assert_int_equal(flag_ms, 60000u * ABBE_STUCK_MIN);
    assert_true(step_fade <= bound);
    assert_true(step_between <= fade_step);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_thermal_inputs_and_faults),
    };
    const struct CMUnitTest stuck_tests[] = {
        cmocka_unit_test(test_stuck_sensor),
    };
    int failed = cmocka_run_group_tests(tests, group_setup, group_teardown);
    return failed + cmocka_run_group_tests(stuck_tests, stuck_group_setup, group_teardown);
}
