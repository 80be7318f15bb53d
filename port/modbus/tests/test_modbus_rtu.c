/* abbe-modbusd over Modbus RTU on a pseudo-terminal pair: the server opens the
 * slave side, the test's libmodbus RTU client talks through the master side.
 * Same scenario as over TCP (upload, stream, compare), plus RTU framing:
 * a damaged frame is dropped, a broadcast is applied without an answer, a
 * request for another unit (and that unit's answer) is ignored. */
#define _XOPEN_SOURCE 600

#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include <errno.h>
#include <fcntl.h>
#include <unistd.h>

#include "abbe/modbus_port.h"
#include "harness.h"
#include "scenario.h"

static mbt_server_t srv;
static modbus_t *ctx;
static int master = -1;
static uint8_t paper[ABBE_MB_STAGING_MAX];
static size_t paper_size;

static int group_setup(void **state)
{
    (void)state;
    static char device[128], spec[160];
    long n = mbt_read_file(ABBE_EXAMPLE_MODEL, paper, sizeof paper);
    if (n <= 0) {
        return -1;
    }
    paper_size = (size_t)n;
    master = posix_openpt(O_RDWR | O_NOCTTY);
    if (master < 0 || grantpt(master) != 0 || unlockpt(master) != 0 || ptsname(master) == NULL) {
        return -1;
    }
    snprintf(device, sizeof device, "%s", ptsname(master));
    snprintf(spec, sizeof spec, "%s:115200:E81", device);
    const char *argv[] = {ABBE_MODBUSD, "--rtu", spec, "--unit", "1", NULL};
    if (mbt_server_start(&srv, NULL, argv, 20000) != 0) {
        return -1;
    }
    /* The client writes and reads the master side directly: no device to open. */
    ctx = modbus_new_rtu(device, 115200, 'E', 8, 1);
    if (ctx == NULL || modbus_set_slave(ctx, 1) != 0 || modbus_set_socket(ctx, master) != 0) {
        return -1;
    }
    modbus_set_response_timeout(ctx, 5, 0);
    return 0;
}

static int group_teardown(void **state)
{
    (void)state;
    int status = mbt_server_stop(&srv);
    if (ctx != NULL) {
        modbus_free(ctx); /* not modbus_close: the master fd is ours */
    }
    if (master >= 0) {
        close(master);
    }
    if (status != 0) {
        fprintf(stderr, "abbe-modbusd exited with status %d\n", status);
    }
    return status == 0 ? 0 : -1;
}

static uint16_t crc16(const uint8_t *p, size_t n)
{
    uint16_t crc = 0xFFFF;
    for (size_t i = 0; i < n; i++) {
        crc ^= p[i];
        for (int b = 0; b < 8; b++) {
            crc = (crc & 1u) ? (uint16_t)((crc >> 1) ^ 0xA001u) : (uint16_t)(crc >> 1);
        }
    }
    return crc;
}

/* Write a raw RTU frame (adds the CRC, low byte first). */
static void send_frame(const uint8_t *f, size_t n)
{
    uint8_t buf[300];
    memcpy(buf, f, n);
    uint16_t c = crc16(f, n);
    buf[n] = (uint8_t)(c & 0xFFu);
    buf[n + 1] = (uint8_t)(c >> 8);
    assert_int_equal(write(master, buf, n + 2), (ssize_t)(n + 2));
}

static void test_identity(void **state)
{
    (void)state;
    uint16_t id[ABBE_MB_ID_COUNT];
    assert_int_equal(modbus_read_registers(ctx, 0, ABBE_MB_ID_COUNT, id), ABBE_MB_ID_COUNT);
    assert_int_equal(id[0], ABBE_MB_MAGIC_HI);
    assert_int_equal(id[1], ABBE_MB_MAGIC_LO);
    assert_int_equal(mbt_get32(&id[ABBE_MB_REG_ID_SELFTEST], 0), ABBE_MB_SELFTEST_VALUE);
    assert_int_equal(id[ABBE_MB_REG_ID_MAX_CLIENTS], 1);
}

static void test_upload_and_stream(void **state)
{
    (void)state;
    int32_t moved = 0;
    abbe_model_t m;
    assert_int_equal(abbe_model_load(&m, paper, paper_size), ABBE_OK);
    assert_int_equal(scn_configure(ctx, 0), 0);
    assert_int_equal(scn_upload(ctx, paper, paper_size, 0), 0);
    assert_int_equal(scn_stream_compare(ctx, paper, paper_size, 0, 120, &moved), 0);
    assert_true(moved > 1000);
    uint32_t crc;
    assert_int_equal(mbt_read32(ctx, ABBE_MB_REG_ID_MODEL_CRC, 0, &crc), 0);
    assert_int_equal(crc, abbe_model_crc(&m));
}

static void test_bad_upload_and_exceptions(void **state)
{
    (void)state;
    static uint8_t bad[ABBE_MB_STAGING_MAX];
    memcpy(bad, paper, paper_size);
    bad[700] ^= 4u;
    assert_int_equal(mbt_upload(ctx, bad, paper_size, abbe_crc32(0, paper, paper_size), 123, 0), -1);
    assert_int_equal(errno, EMBXILVAL);
    uint16_t result;
    assert_int_equal(modbus_read_registers(ctx, ABBE_MB_REG_UP_RESULT, 1, &result), 1);
    assert_int_equal((int16_t)result, ABBE_MB_UP_CRC_MISMATCH);
    uint16_t v[2];
    assert_int_equal(modbus_read_registers(ctx, 0x0FFF, 2, v), -1);
    assert_int_equal(errno, EMBXILADD);
    assert_int_equal(modbus_write_register(ctx, ABBE_MB_REG_CT_ENABLE, 5), -1);
    assert_int_equal(errno, EMBXILVAL);
}

static void test_rtu_framing(void **state)
{
    (void)state;
    uint16_t v = 0;
    /* a frame with a broken CRC is dropped; the next request is answered */
    static const uint8_t damaged[8] = {1, 0x03, 0, 0, 0, 1, 0x00, 0x00};
    assert_int_equal(write(master, damaged, sizeof damaged), (ssize_t)sizeof damaged);
    assert_int_equal(modbus_read_registers(ctx, ABBE_MB_REG_ID_MAGIC, 1, &v), 1);
    assert_int_equal(v, ABBE_MB_MAGIC_HI);

    /* broadcast (unit 0): applied, not answered (an answer would corrupt the
     * reply to the read that follows) */
    static const uint8_t bcast[6] = {0, 0x06, 0x01, 0x09, 0x04, 0xD2}; /* IN_TEMP_X = 1234 */
    send_frame(bcast, sizeof bcast);
    assert_int_equal(modbus_read_registers(ctx, ABBE_MB_REG_IN_TEMP_X, 1, &v), 1);
    assert_int_equal(v, 1234);

    /* a request for unit 7 and unit 7's answer: both ignored */
    static const uint8_t other_req[6] = {7, 0x03, 0, 0, 0, 1};
    static const uint8_t other_rsp[5] = {7, 0x03, 2, 0x12, 0x34};
    send_frame(other_req, sizeof other_req);
    send_frame(other_rsp, sizeof other_rsp);
    assert_int_equal(modbus_read_registers(ctx, ABBE_MB_REG_ID_MAGIC + 1, 1, &v), 1);
    assert_int_equal(v, ABBE_MB_MAGIC_LO);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_identity),
        cmocka_unit_test(test_upload_and_stream),
        cmocka_unit_test(test_bad_upload_and_exceptions),
        cmocka_unit_test(test_rtu_framing),
    };
    return cmocka_run_group_tests_name("modbus_rtu", tests, group_setup, group_teardown);
}
