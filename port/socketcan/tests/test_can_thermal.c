/* The CAN port's thermal frames (docs/can.md, "Thermal frames") over a
 * socketpair(AF_UNIX, SOCK_SEQPACKET) bus carrying struct can_frame records.
 *
 * The node runs the golden format 1.3 table (tests/golden/golden_thermal.*: 16
 * temperatures + the spindle speed, 5 channels). The test sends positions,
 * the five thermal frames every 10th cycle (SYNC 100 ms: a sample per second)
 * and SYNC; every cycle the node's correction must equal, exactly, a shadow
 * compensator with its own thermal state (abbe_comp_step_thermal_q,
 * abbe_thermal_update_q) fed the same values. Then a sensor fault (input 3
 * "no reading"): the runtime holds, flags, the status frame says TempStale,
 * the thermal part fades out without a jump, and comes back. */
#define _POSIX_C_SOURCE 200809L

#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cmocka.h>

#include "abbe_can.h"
#include "abbe_can_driver.h"
#include "abbe_can_linux.h"
#include "can_test_util.h"
#include "golden_thermal.h"
#include "thermal_stuck.h"

#define TH_ID 0x3F0u
#define STATUS_ID 0x1F0u
#define CYCLE_US 100000u
#define SAMPLE_EVERY 10u

typedef struct {
    int peer, node_fd;
    abbe_can_node_t node;
    abbe_can_fd_t fdst;
    abbe_can_driver_t drv;
    abbe_comp_t shadow;
    abbe_model_t sh_model;
    abbe_thermal_model_t sh_tm;
    abbe_thermal_state_t sh_th;
} fixture_t;

static fixture_t fx;

static int setup_blob(const uint8_t *blob, size_t size)
{
    memset(&fx, 0, sizeof fx);
    int sv[2];
    assert_int_equal(socketpair(AF_UNIX, SOCK_SEQPACKET, 0, sv), 0);
    fx.peer = sv[0];
    fx.node_fd = sv[1];
    assert_int_equal(abbe_can_fd_nonblock(fx.peer), ABBE_CAN_OK);
    assert_int_equal(abbe_can_fd_nonblock(fx.node_fd), ABBE_CAN_OK);
    abbe_can_fd_driver_init(&fx.fdst, fx.node_fd, &fx.drv);
    abbe_can_config_t c;
    abbe_can_config_defaults(&c);
    c.fade_cycles = 10;
    c.info_period_cycles = 0;
    c.thermal_enable = 1;
    c.cycle_us = CYCLE_US;
    for (unsigned j = 0; j < 3; j++) {
        c.axis[j].node_id = (uint8_t)(j + 1u);
        c.axis[j].increments_per_mm = 10000.0;
        c.axis[j].warn_nm = 2000000;
        c.axis[j].limit_nm = 4000000;
        c.axis[j].rate_nm_per_cycle = 10000;
    }
    assert_int_equal(abbe_can_node_init(&fx.node, &c), ABBE_CAN_OK);
    assert_int_equal(abbe_can_node_load_model(&fx.node, blob, size),
                     ABBE_CAN_OK);
    /* the shadow: the same compensator settings as the node builds */
    abbe_comp_config_t cc;
    memset(&cc, 0, sizeof cc);
    for (unsigned j = 0; j < 3; j++) {
        cc.warn_nm[j] = c.axis[j].warn_nm;
        cc.limit_nm[j] = c.axis[j].limit_nm;
        cc.rate_nm_per_cycle[j] = c.axis[j].rate_nm_per_cycle;
        cc.axis_sign[j] = 1;
    }
    cc.fade_cycles = c.fade_cycles;
    cc.stale_cycles = c.stale_cycles;
    assert_int_equal(abbe_comp_init(&fx.shadow, &cc, NULL), ABBE_OK);
    assert_int_equal(abbe_comp_enable(&fx.shadow), ABBE_OK);
    assert_int_equal(abbe_thermal_load(&fx.sh_model, &fx.sh_tm, blob, size), ABBE_OK);
    assert_int_equal(abbe_comp_swap_model(&fx.shadow, &fx.sh_model), ABBE_OK);
    assert_int_equal(abbe_thermal_init_q(&fx.sh_th, &fx.sh_tm, CYCLE_US), ABBE_OK);
    return 0;
}

static int setup(void **state)
{
    (void)state;
    return setup_blob(abbe_golden_thermal_blob, abbe_golden_thermal_blob_size);
}

/* the golden table with input ABBE_STUCK_INPUT's stuck check on (2 min, 0.02 K) */
static union { uint32_t align; uint8_t b[ABBE_CAN_BLOB_MAX]; } stuck_blob;

static int setup_stuck(void **state)
{
    (void)state;
    size_t size = abbe_stuck_blob(stuck_blob.b, sizeof stuck_blob.b);
    assert_true(size > 0u);
    return setup_blob(stuck_blob.b, size);
}

static int teardown(void **state)
{
    (void)state;
    close(fx.peer);
    close(fx.node_fd);
    return 0;
}

static void bus_send(abbe_can_frame_t f)
{
    assert_int_equal(abbe_can_fd_write(fx.peer, &f), ABBE_CAN_OK);
}

/* The stuck test's reading of input ABBE_STUCK_INPUT, m degC (-1: the golden one). */
static int32_t stuck_milli = -1;

/* The sample's five thermal frames; no_reading: input whose slot says "no reading". */
static void send_thermal(const abbe_golden_thermal_sample_t *s, int no_reading, int32_t x_sent[17], uint32_t *valid)
{
    *valid = 0;
    for (unsigned g = 0; g < ABBE_CAN_THERMAL_FRAMES; g++) {
        uint8_t d[8] = {0};
        for (unsigned i = 0; i < 4u; i++) {
            unsigned k = 4u * g + i;
            int32_t v = 0;
            if (k < 17u) {
                v = k == 16u ? s->x_milli[k] : s->x_milli[k] / 10; /* rpm; m degC -> 0.01 degC */
                if (k == ABBE_STUCK_INPUT && stuck_milli >= 0) {
                    v = stuck_milli / 10;
                }
                x_sent[k] = k == 16u ? v : 10 * v;
                if ((int)k == no_reading) {
                    v = ABBE_CAN_TEMP_NO_READING;
                } else {
                    *valid |= 1u << k;
                }
            }
            abbe_can_put_u16(&d[2u * i], (uint16_t)(v & 0xFFFF));
        }
        bus_send(ctu_frame(TH_ID + g, 8, d));
    }
}

typedef struct { int32_t corr[3]; abbe_can_status_frame_t st; } answer_t;

static answer_t cycle(uint32_t n, int no_reading, int send_sample)
{
    for (unsigned j = 0; j < 3; j++) {
        bus_send(ctu_i32_frame(0x181u + j, 4, 0, (int32_t)(1000 * (int32_t)j + 5000)));
    }
    int32_t x[17];
    uint32_t valid = 0;
    if (send_sample) {
        /* past the golden record: its last sample again (a wrap's jump would be a STEP fault) */
        uint32_t g = n < abbe_golden_thermal_sample_count ? n : abbe_golden_thermal_sample_count - 1u;
        send_thermal(&abbe_golden_thermal_samples[g], no_reading, x, &valid);
        assert_int_equal(abbe_thermal_update_q(&fx.sh_th, x, valid, SAMPLE_EVERY * CYCLE_US / 1000u), ABBE_OK);
    }
    bus_send(ctu_frame(0x080u, 0, NULL));
    assert_true(abbe_can_node_poll(&fx.node, &fx.drv, 1000u) >= 0);
    answer_t a;
    memset(&a, 0, sizeof a);
    abbe_can_frame_t f;
    int have_status = 0;
    while (abbe_can_fd_read(fx.peer, &f) == ABBE_CAN_OK) {
        if (f.id == STATUS_ID) {
            assert_int_equal(abbe_can_status_decode(&f, &a.st), ABBE_CAN_OK);
            have_status = 1;
        }
    }
    assert_true(have_status);
    memcpy(a.corr, abbe_can_node_output(&fx.node)->corr_nm, sizeof a.corr);
    /* the shadow, the same cycle */
    abbe_comp_input_q_t in;
    memset(&in, 0, sizeof in);
    for (unsigned j = 0; j < 3; j++) {
        in.pos_nm[j] = (1000 * (int32_t)j + 5000) * 100;
        in.temp_mdegc[j] = 20000;
    }
    in.fresh = 1;
    abbe_comp_output_t out;
    assert_int_equal(abbe_comp_step_thermal_q(&fx.shadow, &fx.sh_th, &in, &out), ABBE_OK);
    for (unsigned j = 0; j < 3; j++) {
        assert_int_equal(a.corr[j], out.corr_nm[j]);
    }
    return a;
}

static void test_thermal_frames_and_a_sensor_fault(void **state)
{
    (void)state;
    int32_t prev[3] = {0, 0, 0};
    int32_t max_step = 0, max_step_fault = 0;
    uint32_t n = 0, cyc = 0;
    answer_t a;
    /* 60 s: the thermal part fades in (30 s) and follows the samples */
    for (; cyc < 600u; cyc++) {
        int sample = cyc % SAMPLE_EVERY == 0u;
        a = cycle(n, -1, sample);
        n += (uint32_t)sample;
        for (unsigned j = 0; j < 3; j++) {
            int32_t d = abs(a.corr[j] - prev[j]);
            max_step = cyc > 400u && d > max_step ? d : max_step; /* once every fade-in is over */
            prev[j] = a.corr[j];
        }
    }
    const abbe_thermal_state_t *th = abbe_can_node_thermal(&fx.node);
    assert_non_null(th);
    assert_int_equal(abbe_thermal_flags(th) & (ABBE_THERMAL_F_FAULTS | ABBE_THERMAL_F_HOLD | ABBE_THERMAL_F_FADING), 0u);
    assert_int_equal(a.st.temp_stale, 0);
    int32_t y[5];
    assert_int_equal(abbe_thermal_channels_q(th, y), 5);
    assert_true(y[0] != 0 && y[2] != 0);
    assert_int_equal(abbe_can_node_counters(&fx.node).thermal_samples, n);
    assert_int_equal(abbe_can_node_counters(&fx.node).thermal_frames, 5u * n);
    /* input 3 stops reading for 10 samples: its channels hold and fade out */
    uint32_t reads3 = 0;
    for (unsigned c = 0; c < 5u; c++) {
        reads3 |= ((fx.sh_tm.channel_inputs[c] >> 3) & 1u) << c;
    }
    assert_true(reads3 != 0u);
    for (uint32_t k = 0; k < 100u; k++, cyc++) {
        int sample = cyc % SAMPLE_EVERY == 0u;
        a = cycle(n, 3, sample);
        n += (uint32_t)sample;
        assert_true(abbe_thermal_flags(th) & ABBE_THERMAL_F_OPEN);
        assert_true(abbe_thermal_flags(th) & ABBE_THERMAL_F_HOLD);
        assert_int_equal(abbe_thermal_input_faults(th), 1u << 3);
        assert_int_equal(a.st.temp_stale, 1); /* the status frame says so */
        for (unsigned j = 0; j < 3; j++) {
            int32_t d = abs(a.corr[j] - prev[j]);
            max_step_fault = d > max_step_fault ? d : max_step_fault;
            prev[j] = a.corr[j];
        }
    }
    /* good again: back to running after the fade-out completes, then fade in */
    for (uint32_t k = 0; k < 700u; k++, cyc++) {
        int sample = cyc % SAMPLE_EVERY == 0u;
        a = cycle(n, -1, sample);
        n += (uint32_t)sample;
        for (unsigned j = 0; j < 3; j++) {
            int32_t d = abs(a.corr[j] - prev[j]);
            max_step_fault = d > max_step_fault ? d : max_step_fault;
            prev[j] = a.corr[j];
        }
    }
    assert_int_equal(abbe_thermal_flags(th) & (ABBE_THERMAL_F_FAULTS | ABBE_THERMAL_F_HOLD | ABBE_THERMAL_F_FADING), 0u);
    assert_int_equal(a.st.temp_stale, 0);
    print_message("CAN thermal: largest correction step per cycle %d nm clean, %d nm through the fault\n",
                  max_step, max_step_fault);
    /* the fade moves a channel by at most |y| / 300 cycles per cycle: no jump */
    int32_t bound = max_step;
    for (unsigned c = 0; c < 5u; c++) {
        bound += abs(y[c]) / 300 + 1;
    }
    assert_true(max_step_fault <= bound);
}

static void test_thermal_frame_dlc_and_no_block(void **state)
{
    (void)state;
    uint8_t d[8] = {0};
    bus_send(ctu_frame(TH_ID + 1u, 6, d));
    bus_send(ctu_frame(0x080u, 0, NULL));
    assert_true(abbe_can_node_poll(&fx.node, &fx.drv, 1000u) >= 0);
    abbe_can_frame_t f;
    while (abbe_can_fd_read(fx.peer, &f) == ABBE_CAN_OK) {
    }
    assert_int_equal(abbe_can_node_counters(&fx.node).bad_dlc, 1u);
    assert_int_equal(abbe_can_node_counters(&fx.node).thermal_frames, 0u);
    /* a 1.1 table (no thermal block): frames are taken, nothing runs */
    static uint8_t blob[ABBE_CAN_BLOB_MAX];
    size_t sz = ctu_read_file(CTU_EXAMPLE_MODEL, blob, sizeof blob);
    assert_int_equal(abbe_can_node_load_model(&fx.node, blob, sz), ABBE_CAN_OK);
    bus_send(ctu_frame(0x080u, 0, NULL));
    assert_true(abbe_can_node_poll(&fx.node, &fx.drv, 1000u) >= 0);
    while (abbe_can_fd_read(fx.peer, &f) == ABBE_CAN_OK) {
    }
    assert_null(abbe_can_node_thermal(&fx.node));
}

/* A stuck sensor (the golden table with input ABBE_STUCK_INPUT's stuck check
 * on: 2 min, 0.02 K): the input ramps, then repeats one value for 240 s, then
 * ramps again. The status frame's TempStale bit (the port's thermal fault
 * report) rises exactly 120 s after the last change, the thermal part fades
 * out with no step larger than a fade step, and everything clears when the
 * reading moves again. Every cycle equals the shadow (cycle()). */
#define STUCK_HOLD_FROM 90u  /* samples (1 s apart) */
#define STUCK_HOLD_TO 330u
#define STUCK_SAMPLES 420u

static void test_stuck_sensor(void **state)
{
    (void)state;
    const abbe_thermal_state_t *th = NULL;
    const int32_t base = abbe_golden_thermal_samples[0].x_milli[ABBE_STUCK_INPUT];
    uint32_t reads = 0; /* channels that read the stuck input */
    for (unsigned c = 0; c < fx.sh_tm.n_channels; c++) {
        reads |= ((fx.sh_tm.channel_inputs[c] >> ABBE_STUCK_INPUT) & 1u) << c;
    }
    assert_true(reads != 0u);
    int32_t prev[3] = {0, 0, 0}, step_clean = 0, step_fade = 0, step_between = 0, y_flag[5] = {0};
    uint32_t n = 0, cyc_flag = 0, cyc_clear = 0, cyc_last_change = 0;
    answer_t a;
    memset(&a, 0, sizeof a);
    for (uint32_t cyc = 0; n < STUCK_SAMPLES || cyc % SAMPLE_EVERY != 0u; cyc++) {
        int sample = cyc % SAMPLE_EVERY == 0u;
        if (sample) {
            stuck_milli = abbe_stuck_reading_milli(base, n, STUCK_HOLD_FROM, STUCK_HOLD_TO);
            if (n == STUCK_HOLD_FROM - 1u) {
                cyc_last_change = cyc;
            }
        }
        a = cycle(n, -1, sample);
        n += (uint32_t)sample;
        th = abbe_can_node_thermal(&fx.node);
        assert_non_null(th);
        uint32_t fl = abbe_thermal_flags(th);
        int32_t step = 0;
        for (unsigned j = 0; j < 3; j++) {
            int32_t d = abs(a.corr[j] - prev[j]);
            step = d > step ? d : step;
            prev[j] = a.corr[j];
        }
        if (cyc > 400u && cyc < 10u * STUCK_HOLD_FROM) {
            step_clean = step > step_clean ? step : step_clean; /* faded in, the sensor moving */
        }
        if ((fl & ABBE_THERMAL_F_STUCK) && cyc_flag == 0u) {
            cyc_flag = cyc;
            assert_int_equal(abbe_thermal_channels_q(th, y_flag), 5);
        }
        if (cyc_flag != 0u) { /* the fade-out, the hold, the catch-up and fade-in */
            step_fade = step > step_fade ? step : step_fade;
            if (cyc % SAMPLE_EVERY != 0u) { /* between samples only the fades move it */
                step_between = step > step_between ? step : step_between;
            }
        }
        if (cyc_flag != 0u && cyc_clear == 0u) {
            if (!(fl & ABBE_THERMAL_F_STUCK)) {
                cyc_clear = cyc;
            } else {
                assert_true(fl & ABBE_THERMAL_F_HOLD);
                assert_int_equal(abbe_thermal_input_faults(th), 1u << ABBE_STUCK_INPUT);
                assert_int_equal(a.st.temp_stale, 1); /* the status frame says so */
            }
        }
        if (cyc > 400u && cyc_flag == 0u) {
            assert_int_equal(fl & (ABBE_THERMAL_F_FAULTS | ABBE_THERMAL_F_HOLD | ABBE_THERMAL_F_FADING), 0u);
            assert_int_equal(a.st.temp_stale, 0);
        }
        if (cyc_flag != 0u && cyc == cyc_flag + 301u) { /* the table's fade (30 s) is over: faded out */
            for (unsigned c = 0; c < fx.sh_tm.n_channels; c++) {
                assert_int_equal(fx.sh_th.wq24[c] == 0u, (reads >> c) & 1u);
            }
        }
    }
    assert_true(cyc_flag != 0u);
    assert_true(cyc_clear != 0u);
    /* clears on the first sample that moves (the frames of sample STUCK_HOLD_TO) */
    assert_int_equal(cyc_clear, SAMPLE_EVERY * STUCK_HOLD_TO);
    assert_true(abbe_thermal_events(th) & ABBE_THERMAL_F_STUCK);
    assert_int_equal(abbe_thermal_flags(th) & (ABBE_THERMAL_F_FAULTS | ABBE_THERMAL_F_HOLD | ABBE_THERMAL_F_FADING), 0u);
    assert_int_equal(a.st.temp_stale, 0);
    uint32_t flag_ms = (cyc_flag - cyc_last_change) * (CYCLE_US / 1000u);
    int32_t fade_step = 0;
    for (unsigned c = 0; c < 5u; c++) {
        fade_step += abs(y_flag[c]) / 300 + 1; /* one fade step (100 ms of 30 s) of each channel */
    }
    int32_t bound = step_clean + fade_step;
    print_message("CAN stuck sensor: TempStale %u ms after the last change; largest correction step per cycle "
                  "%d nm clean, %d nm from the flag through the fade-out and back (bound %d), %d nm between samples "
                  "(bound %d); cleared when it moved\n",
                  flag_ms, step_clean, step_fade, bound, step_between, fade_step);
    assert_int_equal(flag_ms, 60000u * ABBE_STUCK_MIN);
    assert_true(step_fade <= bound);
    assert_true(step_between <= fade_step);
    stuck_milli = -1;
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_thermal_frames_and_a_sensor_fault, setup, teardown),
        cmocka_unit_test_setup_teardown(test_thermal_frame_dlc_and_no_block, setup, teardown),
        cmocka_unit_test_setup_teardown(test_stuck_sensor, setup_stuck, teardown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
