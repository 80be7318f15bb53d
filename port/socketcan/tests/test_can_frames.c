/* CAN port pieces: little-endian fields, scaling, candump lines, status
 * codes, and the node driven through the stub target (no OS). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include <cmocka.h>

#include "abbe_can.h"
#include "abbe_can_driver.h"
#include "abbe_can_log.h"
#include "can_test_util.h"

static void test_le_fields(void **state)
{
    (void)state;
    uint8_t b[4];
    abbe_can_put_i32(b, -2);
    assert_memory_equal(b, "\xFE\xFF\xFF\xFF", 4);
    assert_int_equal(abbe_can_get_i32(b), -2);
    abbe_can_put_i32(b, INT32_MIN);
    assert_memory_equal(b, "\x00\x00\x00\x80", 4);
    assert_int_equal(abbe_can_get_i32(b), INT32_MIN);
    abbe_can_put_i32(b, 0x12345678);
    assert_memory_equal(b, "\x78\x56\x34\x12", 4);
    abbe_can_put_u16(b, 0xBEEF);
    assert_int_equal(b[0], 0xEF);
    assert_int_equal(abbe_can_get_u16(b), 0xBEEF);
}

static abbe_can_axis_config_t axis(double ipm, int8_t sign, int32_t origin_nm)
{
    abbe_can_config_t c;
    abbe_can_config_defaults(&c);
    c.axis[0].increments_per_mm = ipm;
    c.axis[0].sign = sign;
    c.axis[0].origin_nm = origin_nm;
    return c.axis[0];
}

static void test_scaling(void **state)
{
    (void)state;
    abbe_can_axis_config_t a = axis(10000.0, 1, 0);
    assert_int_equal(abbe_can_incr_to_nm(&a, 12345), 1234500);
    assert_int_equal(abbe_can_nm_to_incr(&a, 1234549), 12345);
    assert_int_equal(abbe_can_nm_to_incr(&a, 50), 1);     /* half away from zero */
    assert_int_equal(abbe_can_nm_to_incr(&a, -50), -1);
    assert_int_equal(abbe_can_nm_to_incr(&a, 49), 0);
    a = axis(2000.0, -1, -100000000);
    assert_int_equal(abbe_can_incr_to_nm(&a, 1000), -100500000);
    assert_int_equal(abbe_can_nm_to_incr(&a, 1000), -2);  /* 1 um = 2 increments, reversed */
    assert_int_equal(abbe_can_nm_to_incr(&a, -1250), 3);  /* -2.5 -> -3 -> +3 */
    /* saturation both ways */
    a = axis(1e9, 1, 0);
    assert_int_equal(abbe_can_nm_to_incr(&a, 5000000), INT32_MAX);
    assert_int_equal(abbe_can_nm_to_incr(&a, -5000000), INT32_MIN);
    a = axis(1e9, -1, 0);
    assert_int_equal(abbe_can_nm_to_incr(&a, -5000000), INT32_MAX);
    a = axis(0.001, 1, 0);
    assert_int_equal(abbe_can_incr_to_nm(&a, 5), INT32_MAX);
    assert_int_equal(abbe_can_incr_to_nm(&a, -5), INT32_MIN);
    /* 5 mm lead, 2^17 increments per turn */
    a = axis(131072.0 / 5.0, 1, 0);
    assert_int_equal(abbe_can_incr_to_nm(&a, 131072), 5000000);
    assert_int_equal(abbe_can_nm_to_incr(&a, 5000000), 131072);
}

static void test_status_strings(void **state)
{
    (void)state;
    assert_string_equal(abbe_can_status_name(ABBE_E_CRC), "ABBE_E_CRC");
    assert_string_equal(abbe_can_status_name(ABBE_CAN_E_BUSY), "ABBE_CAN_E_BUSY");
    assert_string_equal(abbe_can_strerror(ABBE_E_CRC), abbe_strerror(ABBE_E_CRC));
    assert_string_equal(abbe_can_strerror(12345), "unknown status");
    /* port codes never collide with core codes, and fit the info frame's int8 */
    for (int st = ABBE_CAN_E_PARSE; st <= ABBE_CAN_E_ARG; st++) {
        assert_string_equal(abbe_strerror(st), "unknown status");
        assert_true(st >= -128);
        assert_true(strncmp(abbe_can_status_name(st), "ABBE_CAN_E_", 11) == 0);
    }
    /* every core status has its name (the log says which check refused a
     * model), and the core's codes stay above the port's */
    assert_true((int)ABBE_STATUS_MIN > (int)ABBE_CAN_E_ARG);
    for (int st = ABBE_STATUS_MIN; st < 0; st++) {
        const char *name = abbe_can_status_name(st);
        if (strncmp(name, "ABBE_E_", 7) != 0) {
            fail_msg("status %d has no name: '%s'", st, name);
        }
    }
    assert_string_equal(abbe_can_status_name(ABBE_E_MISMATCH), "ABBE_E_MISMATCH");
    assert_string_equal(abbe_can_status_name(ABBE_STATUS_MIN - 1), "unknown status");
}

static void parse_ok(const char *line, abbe_can_log_entry_t *e)
{
    int st = abbe_can_log_parse(line, e);
    if (st != ABBE_CAN_OK) {
        fail_msg("'%s' did not parse: %d", line, st);
    }
}

static void test_log_lines(void **state)
{
    (void)state;
    abbe_can_log_entry_t e;
    parse_ok("(1700000000.123456) can0 123#DEADBEEF\n", &e);
    assert_int_equal(e.sec, 1700000000u);
    assert_int_equal(e.usec, 123456u);
    assert_string_equal(e.ifname, "can0");
    assert_int_equal(e.frame.id, 0x123u);
    assert_int_equal(e.frame.dlc, 4);
    assert_memory_equal(e.frame.data, "\xDE\xAD\xBE\xEF", 4);

    parse_ok("(0.5) vcan0 12345678#00.11.22", &e); /* short fraction, dotted bytes */
    assert_int_equal(e.usec, 500000u);
    assert_int_equal(e.frame.id, 0x12345678u | ABBE_CAN_EFF_FLAG);
    assert_int_equal(e.frame.dlc, 3);
    parse_ok("(1.000001) can1 080#", &e);
    assert_int_equal(e.frame.id, 0x080u);
    assert_int_equal(e.frame.dlc, 0);
    parse_ok("(1.000001) can1 181#R", &e);
    assert_int_equal(e.frame.id, 0x181u | ABBE_CAN_RTR_FLAG);
    assert_int_equal(e.frame.dlc, 0);
    parse_ok("(1.000001) can1 181#R4 T", &e); /* RTR with length, direction flag */
    assert_int_equal(e.frame.dlc, 4);
    parse_ok("(1.000001) can1 20000004#0004000000000000\r\n", &e);
    assert_int_equal(e.frame.id, ABBE_CAN_ERR_FLAG | 0x4u);
    assert_int_equal(e.frame.dlc, 8);
    parse_ok("(1.000001) can1 123#1122334455667788_C", &e); /* len8_dlc */
    assert_int_equal(e.frame.dlc, 8);

    assert_int_equal(abbe_can_log_parse("(1.0) can0 123##1AABB", &e), ABBE_CAN_E_UNSUPPORTED);
    const char *bad[] = {
        "",
        "1700000000.123456 can0 123#00",     /* no parentheses */
        "(1700000000.123456)can0 123#00",    /* no blank */
        "(1700000000.) can0 123#00",
        "(1700000000.123456) can0 1234#00",  /* 4-digit id */
        "(1700000000.123456) can0 800#00",   /* 11-bit id out of range */
        "(1700000000.123456) can0 123#0",    /* odd digits */
        "(1700000000.123456) can0 123#001122334455667788", /* 9 bytes */
        "(1700000000.123456) can0 123#00 junk",
        "(1700000000.123456) can0",
        "(1700000000.123456) averyveryverylongifname 123#00",
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        if (abbe_can_log_parse(bad[i], &e) != ABBE_CAN_E_PARSE) {
            fail_msg("'%s' should not parse", bad[i]);
        }
    }
}

static void test_log_round_trip(void **state)
{
    (void)state;
    const char *lines[] = {
        "(1700000000.123456) can0 123#DEADBEEF\n",
        "(0000000001.000001) can0 080#\n", /* leading zeros are not kept */
        "(1700000000.000000) vcan0 1ABCDEF0#0102030405060708\n",
        "(1700000000.000010) can0 181#R\n",
        "(1700000000.000010) can0 181#R4\n",
        "(1700000000.999999) can0 20000004#0004000000000000\n",
    };
    const char *want[] = {
        "(1700000000.123456) can0 123#DEADBEEF\n",
        "(1.000001) can0 080#\n",
        "(1700000000.000000) vcan0 1ABCDEF0#0102030405060708\n",
        "(1700000000.000010) can0 181#R\n",
        "(1700000000.000010) can0 181#R4\n",
        "(1700000000.999999) can0 20000004#0004000000000000\n",
    };
    for (size_t i = 0; i < sizeof lines / sizeof lines[0]; i++) {
        abbe_can_log_entry_t e;
        parse_ok(lines[i], &e);
        char buf[128];
        int n = abbe_can_log_format(&e, buf, sizeof buf);
        assert_int_equal(n, (int)strlen(want[i]));
        assert_string_equal(buf, want[i]);
    }
    abbe_can_log_entry_t e;
    parse_ok(lines[0], &e);
    char small[10];
    assert_int_equal(abbe_can_log_format(&e, small, sizeof small), ABBE_CAN_E_ARG);
}

static void base_config(abbe_can_config_t *c)
{
    abbe_can_config_defaults(c);
    for (unsigned j = 0; j < 3; j++) {
        c->axis[j].node_id = (uint8_t)(j + 1u);
        c->axis[j].increments_per_mm = 1000.0;
    }
}

/* The node through the stub target: no OS, no model (zero offsets, NO_MODEL). */
static void test_stub_target(void **state)
{
    (void)state;
    static abbe_can_node_t node;
    abbe_can_config_t c;
    base_config(&c);
    c.info_period_cycles = 3;
    assert_int_equal(abbe_can_node_init(&node, &c), ABBE_CAN_OK);
    abbe_can_stub_t stub;
    abbe_can_driver_t drv;
    abbe_can_stub_init(&stub, &drv);
    for (int k = 0; k < 3; k++) {
        for (unsigned j = 0; j < 3; j++) {
            abbe_can_frame_t f = ctu_i32_frame(0x181u + j, 4, 0, 1000 * k);
            assert_int_equal(abbe_can_stub_inject(&stub, &f), ABBE_CAN_OK);
        }
        abbe_can_frame_t s = ctu_frame(0x080u, 0, NULL);
        assert_int_equal(abbe_can_stub_inject(&stub, &s), ABBE_CAN_OK);
        assert_int_equal(abbe_can_node_poll(&node, &drv, 100u), 4);
    }
    /* 3 cycles x (3 RPDOs + status) + 1 info (3rd cycle) */
    abbe_can_frame_t f;
    int n = 0, info = 0;
    while (abbe_can_stub_take(&stub, &f) == ABBE_CAN_OK) {
        n++;
        if (f.id >= 0x201u && f.id <= 0x203u) {
            assert_int_equal(f.dlc, 4);
            assert_int_equal(abbe_can_get_i32(f.data), 0);
        } else if (f.id == 0x1F0u) {
            abbe_can_status_frame_t s;
            assert_int_equal(abbe_can_status_decode(&f, &s), ABBE_CAN_OK);
            assert_int_equal(s.model_loaded, 0);
            assert_true(s.flags & ABBE_FLAG_NO_MODEL);
            assert_int_equal(s.state, ABBE_COMP_ON);
            assert_int_equal(s.fresh_mask, 7);
        } else {
            assert_int_equal(f.id, 0x2F0u);
            abbe_can_info_frame_t in;
            assert_int_equal(abbe_can_info_decode(&f, &in), ABBE_CAN_OK);
            assert_int_equal(in.model_crc, 0);
            info++;
        }
    }
    assert_int_equal(n, 13);
    assert_int_equal(info, 1);

    /* a full transmit queue: frames are counted as errors, not lost silently */
    for (int k = 0; k < 10; k++) {
        abbe_can_frame_t s = ctu_frame(0x080u, 0, NULL);
        assert_int_equal(abbe_can_stub_inject(&stub, &s), ABBE_CAN_OK);
    }
    assert_int_equal(abbe_can_node_poll(&node, &drv, 100u), 10);
    assert_true(stub.tx_dropped > 0);
    assert_int_equal(abbe_can_node_counters(&node).tx_errors, stub.tx_dropped);

    /* arguments */
    size_t n_tx;
    abbe_can_frame_t tx[ABBE_CAN_MAX_TX];
    assert_int_equal(abbe_can_node_rx(NULL, &f, tx, &n_tx), ABBE_CAN_E_ARG);
    assert_int_equal(abbe_can_node_rx(&node, NULL, tx, &n_tx), ABBE_CAN_E_ARG);
    assert_int_equal(abbe_can_node_poll(&node, NULL, 1), ABBE_CAN_E_ARG);
    assert_int_equal(abbe_can_node_init(NULL, &c), ABBE_CAN_E_ARG);
    c.axis[1].node_id = 0;
    assert_int_equal(abbe_can_node_init(&node, &c), ABBE_CAN_E_CONFIG);
}

/* Shared PDOs: two axes of one drive in one TPDO and one RPDO. */
static void test_shared_pdos(void **state)
{
    (void)state;
    static abbe_can_node_t node;
    abbe_can_config_t c;
    base_config(&c);
    c.axis[0].tpdo_cob_id = c.axis[1].tpdo_cob_id = 0x281u;
    c.axis[0].tpdo_dlc = c.axis[1].tpdo_dlc = 8;
    c.axis[1].position_byte = 4;
    c.axis[0].rpdo_cob_id = c.axis[1].rpdo_cob_id = 0x301u;
    c.axis[0].rpdo_dlc = c.axis[1].rpdo_dlc = 8;
    c.axis[1].offset_byte = 4;
    assert_int_equal(abbe_can_node_init(&node, &c), ABBE_CAN_OK);
    abbe_can_frame_t f = ctu_i32_frame(0x281u, 8, 0, 111);
    abbe_can_put_i32(&f.data[4], 222);
    abbe_can_frame_t tx[ABBE_CAN_MAX_TX];
    size_t n = 9;
    assert_int_equal(abbe_can_node_rx(&node, &f, tx, &n), ABBE_CAN_RX_POSITION);
    assert_int_equal(n, 0);
    f = ctu_i32_frame(0x183u, 4, 0, 333);
    assert_int_equal(abbe_can_node_rx(&node, &f, tx, &n), ABBE_CAN_RX_POSITION);
    f = ctu_frame(0x080u, 0, NULL);
    assert_int_equal(abbe_can_node_rx(&node, &f, tx, &n), ABBE_CAN_RX_SYNC);
    /* one shared RPDO, Z's own, status, info (first cycle: countdown from 100 not yet) */
    assert_int_equal(n, 3);
    assert_int_equal(tx[0].id, 0x301u);
    assert_int_equal(tx[0].dlc, 8);
    assert_int_equal(tx[1].id, 0x203u);
    assert_int_equal(tx[2].id, 0x1F0u);
    abbe_can_status_frame_t s;
    assert_int_equal(abbe_can_status_decode(&tx[2], &s), ABBE_CAN_OK);
    assert_int_equal(s.fresh_mask, 7);
    f = ctu_i32_frame(0x281u, 4, 0, 111); /* shared TPDO with the wrong DLC */
    assert_int_equal(abbe_can_node_rx(&node, &f, tx, &n), ABBE_CAN_RX_BAD_DLC);
}

/* Random frames and random log lines: never a crash or a sanitizer report,
 * and the counters add up (every frame is exactly one kind). */
static uint32_t rng_state = 12345u;
static uint32_t rnd(void)
{
    rng_state ^= rng_state << 13;
    rng_state ^= rng_state >> 17;
    rng_state ^= rng_state << 5;
    return rng_state;
}

static void test_random_input(void **state)
{
    (void)state;
    static abbe_can_node_t node;
    abbe_can_config_t c;
    base_config(&c);
    c.axis[2].tpdo_dlc = 8;
    c.axis[2].statusword_byte = 6;
    assert_int_equal(abbe_can_node_init(&node, &c), ABBE_CAN_OK);
    static uint8_t blob[ABBE_CAN_BLOB_MAX];
    size_t n = ctu_read_file(CTU_EXAMPLE_MODEL, blob, sizeof blob);
    assert_int_equal(abbe_can_node_load_model(&node, blob, n), ABBE_CAN_OK);
    const uint32_t ids[] = {0x080u, 0x181u, 0x182u, 0x183u, 0x270u, 0x555u};
    unsigned kinds[8] = {0};
    for (int i = 0; i < 20000; i++) {
        abbe_can_frame_t f;
        uint32_t r = rnd();
        f.id = (r & 3u) == 0u ? rnd() : ids[(r >> 2) % 6u] | ((r >> 8) & 1u ? ABBE_CAN_RTR_FLAG : 0u);
        f.dlc = (uint8_t)((r >> 12) % 16u > 8u ? (r >> 12) % 16u : ((r >> 12) % 2u ? 4u : (r >> 16) % 9u));
        for (unsigned k = 0; k < 8; k++) {
            f.data[k] = (uint8_t)rnd();
        }
        if (f.id == 0x270u && f.dlc == 1u) {
            f.data[0] = (uint8_t)(f.data[0] % 6u); /* sometimes a real command */
        }
        abbe_can_frame_t tx[ABBE_CAN_MAX_TX];
        size_t n_tx = 0;
        int kind = abbe_can_node_rx(&node, &f, tx, &n_tx);
        assert_true(kind >= 0 && kind < 8);
        kinds[kind]++;
        assert_true(n_tx <= ABBE_CAN_MAX_TX);
        assert_true(kind == ABBE_CAN_RX_SYNC || n_tx == 0u);
        (void)abbe_can_node_take_reload_request(&node);
        static const char alphabet[] = "(0123456789.) can0#RrTxX_ABCDEFabcdef\n";
        char line[96];
        for (unsigned k = 0; k < sizeof line - 1; k++) {
            line[k] = alphabet[rnd() % (sizeof alphabet - 1u)];
        }
        line[sizeof line - 1] = '\0';
        if (r & 0x10000000u) { /* a valid prefix, then a random frame part */
            memcpy(line, "(1.5) can0 ", 11);
            line[11 + rnd() % 30u] = '\0';
        }
        abbe_can_log_entry_t e;
        int st = abbe_can_log_parse(line, &e);
        assert_true(st == ABBE_CAN_OK || st == ABBE_CAN_E_PARSE || st == ABBE_CAN_E_UNSUPPORTED);
    }
    abbe_can_counters_t cnt = abbe_can_node_counters(&node);
    assert_int_equal(cnt.frames_rx, 20000);
    assert_int_equal(cnt.syncs, kinds[ABBE_CAN_RX_SYNC]);
    assert_int_equal(cnt.positions, kinds[ABBE_CAN_RX_POSITION]);
    assert_int_equal(cnt.commands, kinds[ABBE_CAN_RX_COMMAND]);
    assert_int_equal(cnt.bad_dlc, kinds[ABBE_CAN_RX_BAD_DLC]);
    assert_int_equal(cnt.unknown_id, kinds[ABBE_CAN_RX_UNKNOWN]);
    assert_int_equal(cnt.rtr, kinds[ABBE_CAN_RX_RTR]);
    assert_int_equal(cnt.error_frames, kinds[ABBE_CAN_RX_ERROR]);
    assert_int_equal(cnt.bad_command, kinds[ABBE_CAN_RX_BAD_COMMAND]);
    for (unsigned k = 0; k < 8; k++) {
        assert_true(kinds[k] > 0); /* every kind was exercised */
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_le_fields),     cmocka_unit_test(test_scaling),
        cmocka_unit_test(test_status_strings), cmocka_unit_test(test_log_lines),
        cmocka_unit_test(test_log_round_trip), cmocka_unit_test(test_stub_target),
        cmocka_unit_test(test_shared_pdos),    cmocka_unit_test(test_random_input),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
