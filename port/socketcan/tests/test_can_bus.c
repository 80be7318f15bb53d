/* The CAN port's full cycle over a socketpair(AF_UNIX, SOCK_SEQPACKET) bus.
 *
 * The test is the bus: it writes struct can_frame records (drive TPDOs, SYNC,
 * commands, bad frames) into one end, the node reads the other end through
 * the fd target (abbe_can_node_poll), and the test reads back what the node
 * sent. Every offset is checked against a shadow compensator (abbe_comp_step_q
 * run directly on the same positions) and the test's own scaling, exactly.
 * host_tools/tests/test_can_daemon.py checks the daemon against the float64
 * Python reference.
 */
#define _POSIX_C_SOURCE 200809L

#include <math.h>
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

#define PI 3.14159265358979323846

/* Frame map of the test configuration. */
#define TPDO_X 0x181u
#define TPDO_Y 0x182u
#define TPDO_Z 0x185u /* node 5: statusword at byte 0, position at byte 2, DLC 8 */
#define RPDO_X 0x201u
#define RPDO_Y 0x202u
#define RPDO_Z 0x205u /* DLC 8, offset at byte 4 */
#define STATUS_ID 0x1F0u
#define INFO_ID 0x2F0u
#define CMD_ID 0x270u
#define Y_ORIGIN_MM (-100.0)
#define Z_INCR_PER_MM 26214.4
#define SW_OK 0x0237u    /* CiA 402 "operation enabled" */
#define SW_FAULT 0x0208u /* fault bit set */

typedef struct {
    int peer, node_fd;
    abbe_can_node_t node;
    abbe_can_fd_t fdst;
    abbe_can_driver_t drv;
    abbe_comp_t shadow;
    abbe_model_t shadow_model[2];
    uint8_t shadow_blob[2][ABBE_CAN_BLOB_MAX];
    int shadow_slot;
    uint16_t z_statusword;
    char dir[256];
    int32_t last_incr[3];
    int32_t shadow_temp[3]; /* temperatures the shadow compensator is given, m°C */
} fixture_t;

static fixture_t fx;

typedef struct {
    int32_t off[3];
    int have_off[3];
    int n_rpdo;
    int have_status, have_info;
    abbe_can_status_frame_t st;
    abbe_can_info_frame_t info;
    int n_frames;
} answer_t;

/* ---- the test's own scaling (docs/can.md "Scaling") ---------------------- */

static int32_t incr_of_mm(unsigned j, double mm)
{
    switch (j) {
    case 0: return (int32_t)lround(mm * 10000.0);
    case 1: return (int32_t)lround(-(mm - Y_ORIGIN_MM) * 2000.0);
    default: return (int32_t)lround(mm * Z_INCR_PER_MM);
    }
}

static int32_t nm_of_incr(unsigned j, int32_t incr)
{
    switch (j) {
    case 0: return incr * 100;
    case 1: return (int32_t)lround(Y_ORIGIN_MM * 1e6) - incr * 500;
    default: return (int32_t)lround((double)incr * 1e6 / Z_INCR_PER_MM);
    }
}

static int32_t incr_of_corr(unsigned j, int32_t corr_nm)
{
    switch (j) {
    case 0: return (int32_t)lround((double)corr_nm / 100.0);
    case 1: return -(int32_t)lround((double)corr_nm / 500.0);
    default: return (int32_t)lround((double)corr_nm * Z_INCR_PER_MM / 1e6);
    }
}

static void make_config(abbe_can_config_t *c)
{
    abbe_can_config_defaults(c);
    c->fade_cycles = 10;
    c->stale_cycles = 3;
    c->info_period_cycles = 50;
    for (unsigned j = 0; j < 3; j++) {
        abbe_can_axis_config_t *a = &c->axis[j];
        a->warn_nm = 100000;
        a->limit_nm = 200000;
        a->rate_nm_per_cycle = 5000;
    }
    c->axis[0].node_id = 1;
    c->axis[0].increments_per_mm = 10000.0;
    c->axis[1].node_id = 2;
    c->axis[1].increments_per_mm = 2000.0;
    c->axis[1].sign = -1;
    c->axis[1].origin_nm = (int32_t)lround(Y_ORIGIN_MM * 1e6);
    c->axis[2].node_id = 5;
    c->axis[2].increments_per_mm = Z_INCR_PER_MM;
    c->axis[2].tpdo_dlc = 8;
    c->axis[2].statusword_byte = 0;
    c->axis[2].position_byte = 2;
    c->axis[2].rpdo_dlc = 8;
    c->axis[2].offset_byte = 4;
}

static abbe_comp_config_t shadow_config(const abbe_can_config_t *c)
{
    abbe_comp_config_t cc;
    memset(&cc, 0, sizeof cc);
    for (unsigned j = 0; j < 3; j++) {
        cc.warn_nm[j] = c->axis[j].warn_nm;
        cc.limit_nm[j] = c->axis[j].limit_nm;
        cc.rate_nm_per_cycle[j] = c->axis[j].rate_nm_per_cycle;
        cc.axis_sign[j] = c->axis[j].correction_sign;
    }
    cc.fade_cycles = c->fade_cycles;
    cc.stale_cycles = c->stale_cycles;
    return cc;
}

static int shadow_load(const void *blob, size_t size)
{
    int s = fx.shadow_slot;
    memcpy(fx.shadow_blob[s], blob, size);
    int st = abbe_comp_load_model(&fx.shadow, &fx.shadow_model[s], fx.shadow_blob[s], size);
    if (st == ABBE_OK) {
        fx.shadow_slot = 1 - s;
    }
    return st;
}

static int setup(void **state)
{
    (void)state;
    memset(&fx, 0, sizeof fx);
    int sv[2];
    assert_int_equal(socketpair(AF_UNIX, SOCK_SEQPACKET, 0, sv), 0);
    fx.peer = sv[0];
    fx.node_fd = sv[1];
    assert_int_equal(abbe_can_fd_nonblock(fx.peer), ABBE_CAN_OK);
    assert_int_equal(abbe_can_fd_nonblock(fx.node_fd), ABBE_CAN_OK);
    abbe_can_fd_driver_init(&fx.fdst, fx.node_fd, &fx.drv);

    abbe_can_config_t cfg;
    make_config(&cfg);
    assert_int_equal(abbe_can_node_init(&fx.node, &cfg), ABBE_CAN_OK);
    char why[512];
    assert_int_equal(abbe_can_model_load_file(&fx.node, CTU_EXAMPLE_MODEL, why, sizeof why), ABBE_CAN_OK);
    assert_non_null(strstr(why, "loaded"));

    abbe_comp_config_t cc = shadow_config(&cfg);
    assert_int_equal(abbe_comp_init(&fx.shadow, &cc, NULL), ABBE_OK);
    assert_int_equal(abbe_comp_enable(&fx.shadow), ABBE_OK);
    static uint8_t blob[ABBE_CAN_BLOB_MAX];
    size_t n = ctu_read_file(CTU_EXAMPLE_MODEL, blob, sizeof blob);
    assert_int_equal(shadow_load(blob, n), ABBE_OK);
    fx.z_statusword = SW_OK;
    for (unsigned j = 0; j < 3; j++) {
        fx.shadow_temp[j] = 20000;
    }
    ctu_tmpdir(fx.dir, sizeof fx.dir);
    return 0;
}

static int teardown(void **state)
{
    (void)state;
    close(fx.peer);
    close(fx.node_fd);
    ctu_rmtree(fx.dir);
    return 0;
}

/* ---- the bus ---------------------------------------------------------------- */

static void bus_send(abbe_can_frame_t f)
{
    assert_int_equal(abbe_can_fd_write(fx.peer, &f), ABBE_CAN_OK);
}

/* A raw 16-byte record with any length byte (the fd target clamps to 8). */
static void bus_send_raw(uint32_t id, uint8_t len)
{
    uint8_t rec[16];
    memset(rec, 0, sizeof rec);
    memcpy(rec, &id, sizeof id);
    rec[4] = len;
    assert_int_equal(write(fx.peer, rec, sizeof rec), (ssize_t)sizeof rec);
}

static void send_positions(const int32_t incr[3], unsigned mask)
{
    if (mask & 1u) {
        bus_send(ctu_i32_frame(TPDO_X, 4, 0, incr[0]));
    }
    if (mask & 2u) {
        bus_send(ctu_i32_frame(TPDO_Y, 4, 0, incr[1]));
    }
    if (mask & 4u) {
        abbe_can_frame_t f = ctu_i32_frame(TPDO_Z, 8, 2, incr[2]);
        abbe_can_put_u16(&f.data[0], fx.z_statusword);
        bus_send(f);
    }
}

static int pump(void)
{
    int n = abbe_can_node_poll(&fx.node, &fx.drv, 1000u);
    assert_true(n >= 0);
    return n;
}

static answer_t collect(void)
{
    answer_t a;
    memset(&a, 0, sizeof a);
    abbe_can_frame_t f;
    int st;
    while ((st = abbe_can_fd_read(fx.peer, &f)) == ABBE_CAN_OK) {
        a.n_frames++;
        if (f.id == RPDO_X || f.id == RPDO_Y) {
            unsigned j = f.id == RPDO_X ? 0u : 1u;
            assert_int_equal(f.dlc, 4);
            a.off[j] = abbe_can_get_i32(f.data);
            a.have_off[j]++;
            a.n_rpdo++;
        } else if (f.id == RPDO_Z) {
            assert_int_equal(f.dlc, 8);
            a.off[2] = abbe_can_get_i32(&f.data[4]);
            assert_int_equal(abbe_can_get_u32(f.data), 0); /* unused bytes are zero */
            a.have_off[2]++;
            a.n_rpdo++;
        } else if (f.id == STATUS_ID) {
            assert_int_equal(abbe_can_status_decode(&f, &a.st), ABBE_CAN_OK);
            a.have_status++;
        } else if (f.id == INFO_ID) {
            assert_int_equal(abbe_can_info_decode(&f, &a.info), ABBE_CAN_OK);
            a.have_info++;
        } else {
            fail_msg("unexpected frame id 0x%lx", (unsigned long)f.id);
        }
    }
    assert_int_equal(st, ABBE_CAN_E_AGAIN);
    return a;
}

static answer_t sync_cycle(void)
{
    bus_send(ctu_frame(0x080u, 0, NULL));
    pump();
    answer_t a = collect();
    assert_int_equal(a.n_rpdo, 3);
    assert_int_equal(a.have_status, 1);
    return a;
}

static abbe_comp_output_t shadow_step(const int32_t incr[3], int fresh, uint8_t fault_mask)
{
    abbe_comp_input_q_t in;
    memset(&in, 0, sizeof in);
    for (unsigned j = 0; j < 3; j++) {
        in.pos_nm[j] = nm_of_incr(j, incr[j]);
        in.temp_mdegc[j] = fx.shadow_temp[j];
    }
    in.fresh = (uint8_t)fresh;
    in.axis_fault_mask = fault_mask;
    abbe_comp_output_t out;
    assert_int_equal(abbe_comp_step_q(&fx.shadow, &in, &out), ABBE_OK);
    return out;
}

/* One cycle: positions of the axes in mask, SYNC, answer checked against the shadow. */
static answer_t checked_cycle(const int32_t incr[3], unsigned mask, uint8_t fault_mask)
{
    for (unsigned j = 0; j < 3; j++) {
        if (mask & (1u << j)) {
            fx.last_incr[j] = incr[j];
        }
    }
    send_positions(incr, mask);
    answer_t a = sync_cycle();
    abbe_comp_output_t want = shadow_step(fx.last_incr, mask == 7u, fault_mask);
    const abbe_comp_output_t *got = abbe_can_node_output(&fx.node);
    for (unsigned j = 0; j < 3; j++) {
        assert_int_equal(got->corr_nm[j], want.corr_nm[j]);
        assert_int_equal(got->target_nm[j], want.target_nm[j]);
        assert_int_equal(a.off[j], incr_of_corr(j, want.corr_nm[j]));
    }
    assert_int_equal(a.st.flags, want.flags & 0xFFFFu);
    assert_int_equal(a.st.state, (uint8_t)want.state);
    assert_int_equal(a.st.fresh_mask, mask);
    return a;
}

static void circle_incr(int k, int32_t incr[3])
{
    double ang = 2.0 * PI * k / 200.0;
    incr[0] = incr_of_mm(0, 250.0 + 100.0 * cos(ang));
    incr[1] = incr_of_mm(1, -200.0 + 100.0 * sin(ang));
    incr[2] = incr_of_mm(2, -150.0 + 20.0 * sin(2.0 * ang));
}

/* ---- tests -------------------------------------------------------------------- */

/* 400 cycles along a circle: every offset equals the shadow compensator's
 * correction in drive increments; status and info frames as documented. */
static void test_circle(void **state)
{
    (void)state;
    int32_t max_abs = 0;
    int infos = 0;
    uint32_t crc = abbe_model_crc(&fx.shadow_model[0]);
    for (int k = 0; k < 400; k++) {
        int32_t incr[3];
        circle_incr(k, incr);
        answer_t a = checked_cycle(incr, 7u, 0);
        assert_int_equal(a.st.seq, (uint8_t)k);
        assert_int_equal(a.st.model_loaded, 1);
        assert_int_equal(a.st.load_failed, 0);
        for (unsigned j = 0; j < 3; j++) {
            assert_int_equal(a.st.age[j], 0);
            int32_t c = abbe_can_node_output(&fx.node)->corr_nm[j];
            if (abs(c) > max_abs) {
                max_abs = abs(c);
            }
        }
        if (a.have_info) {
            infos++;
            assert_int_equal(a.info.model_crc, crc);
            assert_int_equal(a.info.load_status, 0);
            assert_int_equal(a.info.model_swaps, 1);
            assert_int_equal(a.info.ignored, 0);
            /* the first cycle (after the model load) and every 50th */
            assert_true(k == 0 || (k + 1) % 50 == 0);
        }
        if (k >= 20) {
            assert_int_equal(a.st.flags & (ABBE_FLAG_FADING | ABBE_FLAG_STALE | ABBE_FLAG_INPUT_INVALID), 0);
        }
    }
    assert_int_equal(infos, 1 + 400 / 50);
    assert_true(max_abs > 2000); /* the table gives corrections of several um here */
    abbe_can_counters_t c = abbe_can_node_counters(&fx.node);
    assert_int_equal(c.syncs, 400);
    assert_int_equal(c.positions, 1200);
    assert_int_equal(c.frames_tx, 400 * 4 + infos);
    assert_int_equal(abbe_can_node_ignored(&fx.node), 0);
    assert_int_equal(abbe_can_node_model_crc(&fx.node), crc);
}

/* Every kind of bad frame is counted and ignored; a position in a bad frame
 * does not count as fresh. */
static void test_bad_frames(void **state)
{
    (void)state;
    int32_t incr[3];
    circle_incr(0, incr);
    send_positions(incr, 6u);                          /* Y and Z good */
    bus_send(ctu_i32_frame(TPDO_X, 3, 0, incr[0]));   /* wrong DLC */
    bus_send(ctu_frame(TPDO_Y | ABBE_CAN_RTR_FLAG, 4, NULL)); /* remote request */
    bus_send(ctu_i32_frame(TPDO_X | ABBE_CAN_RTR_FLAG, 4, 0, incr[0]));
    bus_send(ctu_i32_frame(TPDO_X | ABBE_CAN_EFF_FLAG, 4, 0, incr[0])); /* 29-bit id, same number */
    bus_send_raw(TPDO_X, 9);                           /* length byte > 8 */
    bus_send(ctu_frame(0x080u, 2, NULL));              /* SYNC with a wrong DLC: no cycle */
    bus_send(ctu_frame(0x555u, 4, NULL));              /* unknown id */
    bus_send(ctu_frame(0x1234u, 4, NULL));             /* > 11 bits without the EFF flag */
    uint8_t err[8] = {0, 0x04, 0, 0, 0, 0, 0, 0};
    bus_send(ctu_frame(ABBE_CAN_ERR_FLAG | 0x004u, 8, err)); /* controller error frame */
    uint8_t cmd = 0x7F;
    bus_send(ctu_frame(CMD_ID, 1, &cmd));              /* unknown command */
    uint8_t cmd2[2] = {ABBE_CAN_CMD_DISABLE, 0};
    bus_send(ctu_frame(CMD_ID, 2, cmd2));              /* command with a wrong DLC */
    uint8_t junk[8] = {1, 2, 3, 4, 5, 6, 7, 8};
    assert_int_equal(write(fx.peer, junk, sizeof junk), (ssize_t)sizeof junk); /* not a can_frame */
    assert_int_equal(write(fx.peer, junk, 0), 0);      /* an empty record: not the end of the bus */
    assert_int_equal(pump(), 15);
    assert_int_equal(collect().n_frames, 0);           /* nothing answered */

    abbe_can_counters_t c = abbe_can_node_counters(&fx.node);
    assert_int_equal(c.bad_dlc, 4);
    assert_int_equal(c.rtr, 2);
    assert_int_equal(c.unknown_id, 3);
    assert_int_equal(c.error_frames, 1);
    assert_int_equal(c.bad_command, 1);
    assert_int_equal(c.malformed, 2);
    assert_int_equal(c.commands, 0);
    assert_int_equal(c.syncs, 0);
    assert_int_equal(c.positions, 2);
    assert_int_equal(abbe_can_node_ignored(&fx.node), 13);

    answer_t a = checked_cycle(incr, 6u, 0); /* X never arrived: not fresh */
    assert_int_equal(a.st.fresh_mask, 6);
    assert_int_equal(a.st.age[0], 1);
    assert_int_equal(a.st.age[1], 0);
    assert_true(a.st.flags & ABBE_FLAG_INPUT_INVALID);
    assert_false(a.st.flags & ABBE_FLAG_STALE);
    assert_int_equal(a.st.ignored, 13);
    assert_int_equal(a.have_info, 1); /* first cycle after the model load */
    assert_int_equal(a.info.ignored, 13);
    assert_int_equal(a.st.state, ABBE_COMP_ON); /* the malformed DISABLE did nothing */

    /* A SYNC with the CiA 301 counter byte is a SYNC. */
    uint8_t counter = 7;
    send_positions(incr, 7u);
    bus_send(ctu_frame(0x080u, 1, &counter));
    pump();
    a = collect();
    assert_int_equal(a.n_rpdo, 3);
    assert_int_equal(a.st.fresh_mask, 7);
    assert_int_equal(abbe_can_node_counters(&fx.node).syncs, 2);
}

/* The end of the bus is the peer shutting down its end, not an empty record:
 * empty records are counted (also one still queued when the peer shuts down),
 * the frames behind them are handled, and only then does the poll report
 * ABBE_CAN_E_CLOSED (once, not as a stream of empty records). */
static void test_empty_records_and_end_of_bus(void **state)
{
    (void)state;
    int32_t incr[3];
    circle_incr(0, incr);
    assert_int_equal(write(fx.peer, "", 0), 0);
    send_positions(incr, 7u);
    assert_int_equal(write(fx.peer, "", 0), 0);
    answer_t a = sync_cycle();
    assert_int_equal(a.st.fresh_mask, 7);
    assert_int_equal(a.st.ignored, 2);
    assert_int_equal(abbe_can_node_counters(&fx.node).malformed, 2);

    /* an empty record, a SYNC, then the peer shuts down its sending side */
    assert_int_equal(write(fx.peer, "", 0), 0);
    send_positions(incr, 7u);
    bus_send(ctu_frame(0x080u, 0, NULL));
    assert_int_equal(shutdown(fx.peer, SHUT_WR), 0);
    assert_int_equal(abbe_can_node_poll(&fx.node, &fx.drv, 1000u), ABBE_CAN_E_CLOSED);
    a = collect();
    assert_int_equal(a.have_status, 1); /* the SYNC behind the empty record ran */
    assert_int_equal(a.st.ignored, 3);
    abbe_can_counters_t c = abbe_can_node_counters(&fx.node);
    assert_int_equal(c.malformed, 3);
    assert_int_equal(c.syncs, 2);
    abbe_can_frame_t f;
    assert_int_equal(abbe_can_fd_read(fx.node_fd, &f), ABBE_CAN_E_CLOSED); /* and it stays closed */
    assert_int_equal(abbe_can_node_counters(&fx.node).malformed, 3);
}

/* A position missing for stale_cycles cycles trips the watchdog: flag, fade
 * out to zero; positions again: fade back in. Ages count per axis. */
static void test_stale_watchdog(void **state)
{
    (void)state;
    int32_t incr[3];
    int k = 0;
    for (; k < 20; k++) {
        circle_incr(k, incr);
        checked_cycle(incr, 7u, 0);
    }
    for (unsigned j = 0; j < 3; j++) {
        assert_true(abbe_can_node_output(&fx.node)->corr_nm[j] != 0);
    }
    for (int m = 1; m <= 15; m++, k++) {
        circle_incr(k, incr);
        answer_t a = checked_cycle(incr, 5u, 0); /* Y silent */
        assert_int_equal(a.st.age[1], m);
        assert_int_equal(a.st.age[0], 0);
        assert_int_equal(abbe_can_node_age(&fx.node, 1), (uint32_t)m);
        assert_true(a.st.flags & ABBE_FLAG_INPUT_INVALID);
        if (m < 3) {
            assert_false(a.st.flags & ABBE_FLAG_STALE);
        } else {
            assert_true(a.st.flags & ABBE_FLAG_STALE);
        }
    }
    for (unsigned j = 0; j < 3; j++) {
        assert_int_equal(abbe_can_node_output(&fx.node)->corr_nm[j], 0); /* faded out */
    }
    answer_t a;
    for (int m = 0; m < 15; m++, k++) {
        circle_incr(k, incr);
        a = checked_cycle(incr, 7u, 0);
        assert_false(a.st.flags & ABBE_FLAG_STALE);
        assert_int_equal(a.st.age[1], 0);
    }
    assert_false(a.st.flags & ABBE_FLAG_FADING);
    assert_true(abbe_can_node_output(&fx.node)->corr_nm[0] != 0);
    assert_int_equal(abbe_can_node_counters(&fx.node).stale_cycles, 15);
    assert_int_equal(abbe_can_node_comp_stats(&fx.node).stale_events, 1);

    /* An axis that never reports: its age counts from the start, saturated at 255 in the frame. */
    for (int m = 0; m < 300; m++) {
        send_positions(incr, 3u);
        a = sync_cycle();
    }
    assert_int_equal(a.st.age[2], 255);
    assert_int_equal(abbe_can_node_age(&fx.node, 2), 300);
}

/* Write a variant of the example model: reference point X shifted, CRC fixed. */
static void write_model(const char *name, int32_t shift_nm, size_t keep, int corrupt, size_t *size_out)
{
    static uint8_t blob[ABBE_CAN_BLOB_MAX + 4096];
    size_t n = ctu_read_file(CTU_EXAMPLE_MODEL, blob, sizeof blob);
    ctu_put_i32(blob + 24, ctu_get_i32(blob + 24) + shift_nm);
    ctu_fix_crc(blob);
    if (corrupt) {
        blob[300] ^= 0x40u; /* a coefficient byte: the CRC no longer matches */
    }
    if (keep == (size_t)-1) {
        n = sizeof blob; /* oversized: the table followed by zeros */
        memset(blob + 1412, 0, sizeof blob - 1412);
    } else if (keep > 0) {
        n = keep;
    }
    char path[512];
    snprintf(path, sizeof path, "%s/%s", fx.dir, name);
    ctu_write_file(path, blob, n);
    if (size_out != NULL) {
        *size_out = n;
    }
}

static void path_of(const char *name, char *path, size_t size)
{
    snprintf(path, size, "%s/%s", fx.dir, name);
}

/* A good model, asked for by a RELOAD command, swaps at the next SYNC; bad
 * ones (corrupt, truncated, missing, too big, or while one is queued) leave
 * the running model in place and say why. */
static void test_model_swap(void **state)
{
    (void)state;
    int32_t incr[3];
    int k = 0;
    for (; k < 5; k++) {
        circle_incr(k, incr);
        checked_cycle(incr, 7u, 0);
    }
    uint32_t crc0 = abbe_can_node_model_crc(&fx.node);
    char path[512], why[1024];

    /* good, by command */
    size_t n;
    write_model("good.bin", 50000000, 0, 0, &n);
    path_of("good.bin", path, sizeof path);
    uint8_t cmd = ABBE_CAN_CMD_RELOAD;
    bus_send(ctu_frame(CMD_ID, 1, &cmd));
    circle_incr(k++, incr);
    send_positions(incr, 7u);
    bus_send(ctu_frame(0x080u, 0, NULL));
    assert_int_equal(pump(), 1); /* stops after RELOAD so the model can be loaded first */
    assert_int_equal(abbe_can_node_take_reload_request(&fx.node), 1);
    assert_int_equal(abbe_can_node_take_reload_request(&fx.node), 0);
    assert_int_equal(abbe_can_model_load_file(&fx.node, path, why, sizeof why), ABBE_CAN_OK);
    assert_non_null(strstr(why, "takes effect at the next SYNC"));
    assert_int_equal(abbe_can_node_model_crc(&fx.node), crc0); /* not yet */
    static uint8_t blob[ABBE_CAN_BLOB_MAX];
    assert_int_equal(ctu_read_file(path, blob, sizeof blob), n);
    assert_int_equal(shadow_load(blob, n), ABBE_OK);
    pump(); /* positions + SYNC */
    answer_t a = collect();
    fx.last_incr[0] = incr[0], fx.last_incr[1] = incr[1], fx.last_incr[2] = incr[2];
    abbe_comp_output_t want = shadow_step(incr, 1, 0);
    assert_true(want.flags & ABBE_FLAG_MODEL_SWAPPED);
    assert_int_equal(a.st.flags, want.flags & 0xFFFFu);
    for (unsigned j = 0; j < 3; j++) {
        assert_int_equal(a.off[j], incr_of_corr(j, want.corr_nm[j]));
    }
    uint32_t crc1 = abbe_can_node_model_crc(&fx.node);
    assert_true(crc1 != crc0);
    assert_int_equal(a.have_info, 1);
    assert_int_equal(a.info.model_crc, crc1);
    assert_int_equal(a.info.model_swaps, 2);
    assert_int_equal(a.info.load_status, 0);
    assert_int_equal(abbe_can_get_u32(blob + n - 4), crc1);

    /* bad ones */
    struct {
        const char *name;
        size_t keep;
        int corrupt;
        int status;
        const char *says;
    } bad[] = {
        {"crc.bin", 0, 1, ABBE_E_CRC, "ABBE_E_CRC"},
        {"short.bin", 100, 0, ABBE_E_TRUNCATED, "ABBE_E_TRUNCATED"},
        {"big.bin", (size_t)-1, 0, ABBE_CAN_E_TOO_BIG, "larger than 16384 bytes"},
        {"missing.bin", 0, 0, ABBE_CAN_E_IO, "cannot open"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        if (strcmp(bad[i].name, "missing.bin") != 0) {
            write_model(bad[i].name, 0, bad[i].keep, bad[i].corrupt, NULL);
        }
        path_of(bad[i].name, path, sizeof path);
        assert_int_equal(abbe_can_model_load_file(&fx.node, path, why, sizeof why), bad[i].status);
        assert_non_null(strstr(why, "refused"));
        assert_non_null(strstr(why, bad[i].says));
        assert_non_null(strstr(why, "kept"));
        assert_false(abbe_can_node_model_pending(&fx.node));
        circle_incr(k++, incr);
        a = checked_cycle(incr, 7u, 0); /* the shadow did not swap either */
        assert_int_equal(a.st.load_failed, 1);
        assert_int_equal(a.have_info, 1);
        assert_int_equal(a.info.load_status, (int8_t)bad[i].status);
        assert_int_equal(a.info.model_crc, crc1);
        assert_int_equal(abbe_can_node_model_crc(&fx.node), crc1);
        assert_false(a.st.flags & ABBE_FLAG_MODEL_SWAPPED);
    }

    /* one queued already: the second load is refused as busy */
    path_of("good.bin", path, sizeof path);
    write_model("other.bin", -30000000, 0, 0, &n);
    assert_int_equal(abbe_can_model_load_file(&fx.node, path, why, sizeof why), ABBE_CAN_OK);
    char other[512];
    path_of("other.bin", other, sizeof other);
    assert_int_equal(abbe_can_model_load_file(&fx.node, other, why, sizeof why), ABBE_CAN_E_BUSY);
    assert_non_null(strstr(why, "ABBE_CAN_E_BUSY"));
    assert_null(abbe_can_node_model_buffer(&fx.node, NULL));
    /* the same bytes as the running model: swapping is harmless, the shadow does the same */
    n = ctu_read_file(path, blob, sizeof blob);
    assert_int_equal(shadow_load(blob, n), ABBE_OK);
    circle_incr(k++, incr);
    a = checked_cycle(incr, 7u, 0);
    assert_true(a.st.flags & ABBE_FLAG_MODEL_SWAPPED);
    assert_int_equal(a.st.load_failed, 1); /* the last attempt (busy) failed */
    assert_int_equal(abbe_can_model_load_file(&fx.node, other, why, sizeof why), ABBE_CAN_OK);
    n = ctu_read_file(other, blob, sizeof blob);
    assert_int_equal(shadow_load(blob, n), ABBE_OK);
    circle_incr(k++, incr);
    a = checked_cycle(incr, 7u, 0);
    assert_int_equal(a.st.load_failed, 0);
    assert_int_equal(a.info.model_crc, abbe_can_get_u32(blob + n - 4));

    abbe_can_counters_t c = abbe_can_node_counters(&fx.node);
    assert_int_equal(c.model_loads_ok, 4);
    assert_int_equal(c.model_loads_failed, 5);
    assert_int_equal(c.commands, 1);
}

/* Commands: DISABLE fades out, ENABLE fades in; a drive's statusword fault
 * bit fades only that axis. */
static void test_commands_and_axis_fault(void **state)
{
    (void)state;
    int32_t incr[3];
    int k = 0;
    for (; k < 15; k++) {
        circle_incr(k, incr);
        checked_cycle(incr, 7u, 0);
    }
    uint8_t cmd = ABBE_CAN_CMD_DISABLE;
    bus_send(ctu_frame(CMD_ID, 1, &cmd));
    pump();
    assert_int_equal(abbe_comp_disable(&fx.shadow), ABBE_OK);
    answer_t a;
    for (int m = 0; m < 12; m++, k++) {
        circle_incr(k, incr);
        a = checked_cycle(incr, 7u, 0);
    }
    assert_int_equal(a.st.state, ABBE_COMP_OFF);
    for (unsigned j = 0; j < 3; j++) {
        assert_int_equal(a.off[j], 0);
    }
    cmd = ABBE_CAN_CMD_ENABLE;
    bus_send(ctu_frame(CMD_ID, 1, &cmd));
    pump();
    assert_int_equal(abbe_comp_enable(&fx.shadow), ABBE_OK);
    for (int m = 0; m < 12; m++, k++) {
        circle_incr(k, incr);
        a = checked_cycle(incr, 7u, 0);
    }
    assert_int_equal(a.st.state, ABBE_COMP_ON);
    assert_true(a.off[2] != 0);
    cmd = ABBE_CAN_CMD_RESET; /* clears a fault and disables */
    bus_send(ctu_frame(CMD_ID, 1, &cmd));
    pump();
    assert_int_equal(abbe_comp_reset(&fx.shadow), ABBE_OK);
    circle_incr(k++, incr);
    a = checked_cycle(incr, 7u, 0);
    assert_int_equal(a.st.state, ABBE_COMP_OFF);
    cmd = ABBE_CAN_CMD_ENABLE;
    bus_send(ctu_frame(CMD_ID, 1, &cmd));
    pump();
    assert_int_equal(abbe_comp_enable(&fx.shadow), ABBE_OK);
    for (int m = 0; m < 12; m++, k++) {
        circle_incr(k, incr);
        checked_cycle(incr, 7u, 0);
    }
    assert_int_equal(abbe_can_node_counters(&fx.node).commands, 4);

    fx.z_statusword = SW_FAULT;
    for (int m = 0; m < 12; m++, k++) {
        circle_incr(k, incr);
        a = checked_cycle(incr, 7u, 0x4u);
        assert_true(a.st.flags & ABBE_FLAG_AXIS_FAULT);
    }
    assert_int_equal(a.off[2], 0);
    assert_true(a.off[0] != 0);
    fx.z_statusword = SW_OK;
    for (int m = 0; m < 12; m++, k++) {
        circle_incr(k, incr);
        a = checked_cycle(incr, 7u, 0);
    }
    assert_true(a.off[2] != 0);
}

/* Direction from position deltas with a deadband, seen through the backlash
 * term: approaching a point from below and from above differs by the
 * reversal B; a move back smaller than the deadband does not reverse. */
static void test_direction_deadband(void **state)
{
    (void)state;
    static uint8_t blob[ABBE_CAN_BLOB_MAX];
    size_t n = ctu_read_file(CTU_EXAMPLE_MODEL, blob, sizeof blob);
    const int32_t b_nm = 10000, takeup_nm = 20000;
    abbe_can_put_u32(blob + 20, abbe_can_get_u32(blob + 20) | ABBE_FEATURE_BACKLASH);
    ctu_put_i32(blob + 64 + 28, b_nm * 256);   /* X reversal, 2^-8 nm */
    ctu_put_i32(blob + 64 + 32, takeup_nm);
    ctu_fix_crc(blob);
    char path[512], why[512];
    path_of("backlash.bin", path, sizeof path);
    ctu_write_file(path, blob, n);
    int32_t incr[3] = {incr_of_mm(0, 200.0), incr_of_mm(1, -200.0), incr_of_mm(2, -150.0)};
    send_positions(incr, 7u);
    sync_cycle();
    assert_int_equal(abbe_can_model_load_file(&fx.node, path, why, sizeof why), ABBE_CAN_OK);

    /* X from 199 mm up to 200 mm in 10 um steps (deadband 1 um) */
    const int32_t target_incr = incr_of_mm(0, 200.0);
    for (int32_t x = target_incr - 10000; x <= target_incr; x += 100) {
        incr[0] = x;
        send_positions(incr, 7u);
        sync_cycle();
    }
    for (int m = 0; m < 20; m++) { /* standstill: fade completes, state kept */
        send_positions(incr, 7u);
        sync_cycle();
    }
    int32_t t_up = abbe_can_node_output(&fx.node)->target_nm[0];
    /* back by 0.5 um (5 increments): inside the deadband, no reversal (a
     * reversal would move the state by 0.5/20 of the way: 125 nm of target) */
    incr[0] = target_incr - 5;
    send_positions(incr, 7u);
    sync_cycle();
    assert_true(abs(abbe_can_node_output(&fx.node)->target_nm[0] - t_up) <= 5);
    /* back by 1.5 um in all: beyond the deadband, the take-up starts */
    incr[0] = target_incr - 15;
    send_positions(incr, 7u);
    sync_cycle();
    assert_true(t_up - abbe_can_node_output(&fx.node)->target_nm[0] > 200);
    /* up to 201 mm and back down to 200 mm */
    for (int32_t x = target_incr; x <= target_incr + 10000; x += 100) {
        incr[0] = x;
        send_positions(incr, 7u);
        sync_cycle();
    }
    for (int32_t x = target_incr + 10000; x >= target_incr; x -= 100) {
        incr[0] = x;
        send_positions(incr, 7u);
        sync_cycle();
    }
    int32_t t_down = abbe_can_node_output(&fx.node)->target_nm[0];
    /* dX gains -s*B/2 through -d_x(x); the correction is -dX: + side minus - side = B */
    assert_true(abs((t_up - t_down) - b_nm) <= 2);
}

/* ---- temperatures ---------------------------------------------------------------- */

#define TEMP_ID 0x370u /* 0x300 + the compensator's node id 0x70 */

static abbe_can_frame_t temp_frame(int32_t x_cdegc, int32_t y_cdegc, int32_t z_cdegc, uint8_t dlc)
{
    abbe_can_frame_t f = ctu_frame(TEMP_ID, dlc, NULL);
    const int32_t v[3] = {x_cdegc, y_cdegc, z_cdegc};
    for (unsigned j = 0; j < 3; j++) {
        abbe_can_put_u16(&f.data[2u * j], (uint16_t)(v[j] < 0 ? v[j] + 65536 : v[j]));
    }
    return f;
}

/* The example table with thermal terms on every axis (12 ppm/K, 1 um/K offset
 * on X, reference 20 degC), into the node (restarted with the temperature
 * frame enabled) and the shadow. */
static void start_thermal(uint16_t stale_cycles)
{
    static uint8_t blob[ABBE_CAN_BLOB_MAX];
    size_t n = ctu_read_file(CTU_EXAMPLE_MODEL, blob, sizeof blob);
    abbe_can_put_u32(blob + 20, abbe_can_get_u32(blob + 20) | ABBE_FEATURE_THERMAL);
    for (unsigned j = 0; j < 3; j++) {
        uint8_t *rec = blob + 64 + 64 * j;
        ctu_put_i32(rec + 36, 13510799);            /* 12 ppm/K */
        ctu_put_i32(rec + 40, j == 0 ? 65536 : 0);  /* X: 1 um/K */
        ctu_put_i32(rec + 44, 20000);
    }
    ctu_fix_crc(blob);
    abbe_can_config_t cfg;
    make_config(&cfg);
    cfg.temp_enable = 1;
    cfg.temp_stale_cycles = stale_cycles;
    cfg.axis[2].temp_mdegc = 23000; /* Z has no sensor: its fixed temperature */
    assert_int_equal(abbe_can_node_init(&fx.node, &cfg), ABBE_CAN_OK);
    assert_int_equal(abbe_can_node_load_model(&fx.node, blob, n), ABBE_CAN_OK);
    abbe_comp_config_t cc = shadow_config(&cfg);
    assert_int_equal(abbe_comp_init(&fx.shadow, &cc, NULL), ABBE_OK);
    assert_int_equal(abbe_comp_enable(&fx.shadow), ABBE_OK);
    assert_int_equal(shadow_load(blob, n), ABBE_OK);
    fx.shadow_temp[0] = 20000;
    fx.shadow_temp[1] = 20000;
    fx.shadow_temp[2] = 23000;
}

/* The temperature frame feeds the thermal term: every cycle equals the shadow
 * compensator given the same temperatures; bad frames change nothing and are
 * counted; TEMP_STALE until the first frame, after stale_cycles without one,
 * and when an axis that had readings stops getting them. */
static void test_temperature_frame(void **state)
{
    (void)state;
    start_thermal(5);
    int32_t incr[3];
    int k = 0;
    answer_t a;
    for (; k < 15; k++) { /* no temperature frame yet: axis temp_c, TEMP_STALE */
        circle_incr(k, incr);
        a = checked_cycle(incr, 7u, 0);
        assert_int_equal(a.st.temp_stale, 1);
    }
    int32_t t20 = abbe_can_node_output(&fx.node)->target_nm[0];

    /* X 30 degC, Y 18.5 degC, Z no reading (keeps its temp_c) */
    bus_send(temp_frame(3000, 1850, ABBE_CAN_TEMP_NO_READING, 6));
    fx.shadow_temp[0] = 30000;
    fx.shadow_temp[1] = 18500;
    a = checked_cycle(incr, 7u, 0); /* same positions: only the temperature changed */
    assert_int_equal(a.st.temp_stale, 0);
    assert_int_equal(abbe_can_node_temp_mdegc(&fx.node, 0), 30000);
    assert_int_equal(abbe_can_node_temp_mdegc(&fx.node, 2), 23000);
    assert_int_equal(abbe_can_node_counters(&fx.node).temperatures, 1);
    for (int m = 0; m < 10; m++) { /* let the rate limit catch up */
        bus_send(temp_frame(3000, 1850, ABBE_CAN_TEMP_NO_READING, 6));
        a = checked_cycle(incr, 7u, 0);
    }
    /* 10 K warmer on X: its 1 um/K offset alone moves the target by 10 um
     * (the expansion adds or takes 12 ppm/K of the lever from the reference) */
    int32_t t30 = abbe_can_node_output(&fx.node)->target_nm[0];
    assert_true(abs(t30 - t20) > 9000);

    /* bad frames: wrong DLC, a value out of range; neither changes a temperature */
    uint32_t ignored = abbe_can_node_ignored(&fx.node);
    bus_send(temp_frame(2500, 2500, 2500, 5));
    bus_send(temp_frame(2500, 15001, 2500, 6));
    bus_send(temp_frame(-5001, 2500, 2500, 6));
    bus_send(temp_frame(0x7FFF, 2500, 2500, 6));
    a = checked_cycle(incr, 7u, 0);
    abbe_can_counters_t c = abbe_can_node_counters(&fx.node);
    assert_int_equal(c.bad_value, 3);
    assert_int_equal(abbe_can_node_ignored(&fx.node), ignored + 4);
    assert_int_equal(a.st.ignored, (uint8_t)(ignored + 4));
    assert_int_equal(abbe_can_node_temp_mdegc(&fx.node, 1), 18500);
    /* the range ends are accepted */
    bus_send(temp_frame(-5000, 15000, ABBE_CAN_TEMP_NO_READING, 6));
    fx.shadow_temp[0] = -50000;
    fx.shadow_temp[1] = 150000;
    a = checked_cycle(incr, 7u, 0);
    bus_send(temp_frame(2000, 2000, ABBE_CAN_TEMP_NO_READING, 6));
    fx.shadow_temp[0] = fx.shadow_temp[1] = 20000;
    a = checked_cycle(incr, 7u, 0);

    /* the frames stop: stale after 5 cycles, the last temperatures held */
    for (int m = 1; m <= 8; m++, k++) {
        circle_incr(k, incr);
        a = checked_cycle(incr, 7u, 0);
        assert_int_equal(a.st.temp_stale, m >= 5 ? 1 : 0);
        assert_int_equal(abbe_can_node_temp_age(&fx.node, 0), (uint32_t)m);
    }
    assert_int_equal(abbe_can_node_temp_age(&fx.node, 2), UINT32_MAX); /* never a reading */
    /* frames again: current at once */
    for (int m = 0; m < 3; m++, k++) {
        bus_send(temp_frame(2100, 2050, ABBE_CAN_TEMP_NO_READING, 6));
        fx.shadow_temp[0] = 21000;
        fx.shadow_temp[1] = 20500;
        circle_incr(k, incr);
        a = checked_cycle(incr, 7u, 0);
        assert_int_equal(a.st.temp_stale, 0);
    }
    /* the frames go on but Y's sensor has gone (no reading): stale after 5
     * cycles, Y holds its last reading; Z (never a reading) does not count */
    for (int m = 1; m <= 8; m++, k++) {
        bus_send(temp_frame(2200, ABBE_CAN_TEMP_NO_READING, ABBE_CAN_TEMP_NO_READING, 6));
        fx.shadow_temp[0] = 22000;
        circle_incr(k, incr);
        a = checked_cycle(incr, 7u, 0);
        assert_int_equal(a.st.temp_stale, m >= 5 ? 1 : 0);
        assert_int_equal(abbe_can_node_temp_age(&fx.node, 1), (uint32_t)m);
        assert_int_equal(abbe_can_node_temp_age(&fx.node, ABBE_AXES), 0);
    }
    assert_int_equal(abbe_can_node_temp_mdegc(&fx.node, 1), 20500);
    assert_int_equal(abbe_can_node_counters(&fx.node).temperatures, 11 + 2 + 3 + 8);

    /* with the frame disabled its id is an unknown id */
    abbe_can_config_t cfg = *abbe_can_node_config(&fx.node);
    cfg.temp_enable = 0;
    assert_int_equal(abbe_can_node_init(&fx.node, &cfg), ABBE_CAN_OK);
    abbe_can_frame_t tx[ABBE_CAN_MAX_TX];
    size_t n_tx;
    abbe_can_frame_t f = temp_frame(2000, 2000, 2000, 6);
    assert_int_equal(abbe_can_node_rx(&fx.node, &f, tx, &n_tx), ABBE_CAN_RX_UNKNOWN);
    assert_int_equal(abbe_can_node_temp_mdegc(&fx.node, 2), 23000);
    assert_int_equal(abbe_can_node_temp_stale(&fx.node), 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_circle, setup, teardown),
        cmocka_unit_test_setup_teardown(test_bad_frames, setup, teardown),
        cmocka_unit_test_setup_teardown(test_empty_records_and_end_of_bus, setup, teardown),
        cmocka_unit_test_setup_teardown(test_stale_watchdog, setup, teardown),
        cmocka_unit_test_setup_teardown(test_model_swap, setup, teardown),
        cmocka_unit_test_setup_teardown(test_commands_and_axis_fault, setup, teardown),
        cmocka_unit_test_setup_teardown(test_direction_deadband, setup, teardown),
        cmocka_unit_test_setup_teardown(test_temperature_frame, setup, teardown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
