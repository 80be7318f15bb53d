/* abbe-modbusd over Modbus TCP on 127.0.0.1, port chosen at run time, driven
 * by libmodbus clients. The server starts with a ready signal and is stopped
 * by its pid; its exit status (0, and ASan-clean in sanitizer builds) is
 * checked at the end. No sleeps: waiting for the server to notice something is
 * a bounded loop of requests. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include <arpa/inet.h>
#include <errno.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include "abbe/modbus_port.h"
#include "golden_data.h"
#include "harness.h"
#include "scenario.h"

#define MAX_CLIENTS 4

static mbt_server_t srv;
static modbus_t *ctx; /* the main client */
static uint8_t paper[ABBE_MB_STAGING_MAX];
static size_t paper_size;
static const uint8_t *full;
static size_t full_size;

static uint32_t rd32(modbus_t *c, int addr)
{
    uint32_t v = 0;
    assert_int_equal(mbt_read32(c, addr, ABBE_MB_WORD_ORDER_HIGH_FIRST, &v), 0);
    return v;
}

static uint16_t rd1(modbus_t *c, int addr)
{
    uint16_t v = 0;
    assert_int_equal(modbus_read_registers(c, addr, 1, &v), 1);
    return v;
}

static uint32_t table_crc(const uint8_t *blob, size_t size)
{
    abbe_model_t m;
    assert_int_equal(abbe_model_load(&m, blob, size), ABBE_OK);
    return abbe_model_crc(&m);
}

/* Poll reg from c until it equals want: at most 2000 requests (no sleeps). */
static int wait_reg(modbus_t *c, int reg, uint16_t want)
{
    for (int i = 0; i < 2000; i++) {
        if (rd1(c, reg) == want) {
            return 0;
        }
    }
    return -1;
}

static void one_cycle(void)
{
    assert_int_equal(modbus_write_register(ctx, ABBE_MB_REG_IN_CYCLE, 1), 1);
}

static int group_setup(void **state)
{
    (void)state;
    long n = mbt_read_file(ABBE_EXAMPLE_MODEL, paper, sizeof paper);
    if (n <= 0) {
        return -1;
    }
    paper_size = (size_t)n;
    for (uint32_t i = 0; i < abbe_golden_table_count; i++) {
        if (strcmp(abbe_golden_tables[i].name, "full") == 0) {
            full = abbe_golden_tables[i].blob;
            full_size = abbe_golden_tables[i].blob_size;
        }
    }
    const char *argv[] = {ABBE_MODBUSD, "--tcp", "127.0.0.1:0", "--max-clients", "4",
                          "--upload-timeout-ms", "300", NULL};
    if (full == NULL || mbt_server_start(&srv, NULL, argv, 20000) != 0) {
        return -1;
    }
    ctx = mbt_tcp_client(srv.port);
    return ctx != NULL ? 0 : -1;
}

static int group_teardown(void **state)
{
    (void)state;
    if (ctx != NULL) {
        modbus_close(ctx);
        modbus_free(ctx);
    }
    int status = mbt_server_stop(&srv);
    if (status != 0) {
        fprintf(stderr, "abbe-modbusd exited with status %d\n", status);
    }
    return status == 0 ? 0 : -1;
}

/* ---- identity ---------------------------------------------------------------------- */

static void test_identity(void **state)
{
    (void)state;
    uint16_t id[ABBE_MB_ID_COUNT];
    assert_int_equal(modbus_read_registers(ctx, 0, ABBE_MB_ID_COUNT, id), ABBE_MB_ID_COUNT);
    assert_int_equal(id[0], ABBE_MB_MAGIC_HI);
    assert_int_equal(id[1], ABBE_MB_MAGIC_LO);
    assert_int_equal(id[ABBE_MB_REG_ID_LIB_MAJOR], ABBE_VERSION_MAJOR);
    assert_int_equal(id[ABBE_MB_REG_ID_LIB_MINOR], ABBE_VERSION_MINOR);
    assert_int_equal(id[ABBE_MB_REG_ID_LIB_PATCH], ABBE_VERSION_PATCH);
    assert_int_equal(id[ABBE_MB_REG_ID_FMT_MAJOR], ABBE_TABLE_FORMAT_MAJOR);
    assert_int_equal(id[ABBE_MB_REG_ID_FMT_MINOR], ABBE_TABLE_FORMAT_MINOR);
    assert_int_equal(id[ABBE_MB_REG_ID_MAX_CLIENTS], MAX_CLIENTS);
    assert_int_equal(mbt_get32(&id[ABBE_MB_REG_ID_SELFTEST], 0), ABBE_MB_SELFTEST_VALUE);
    /* FC04 reads the same map */
    uint16_t in[2];
    assert_int_equal(modbus_read_input_registers(ctx, ABBE_MB_REG_ID_SELFTEST, 2, in), 2);
    assert_int_equal(in[0], 0x1234);
    /* word order: the self-test register shows the setting */
    assert_int_equal(modbus_write_register(ctx, ABBE_MB_REG_CT_WORD_ORDER, 1), 1);
    assert_int_equal(modbus_read_registers(ctx, ABBE_MB_REG_ID_SELFTEST, 2, in), 2);
    assert_int_equal(in[0], 0x5678);
    assert_int_equal(in[1], 0x1234);
    assert_int_equal(modbus_write_register(ctx, ABBE_MB_REG_CT_WORD_ORDER, 0), 1);
    assert_int_equal(rd32(ctx, ABBE_MB_REG_ID_SELFTEST), ABBE_MB_SELFTEST_VALUE);
}

/* ---- the end-to-end scenario ---------------------------------------------------------------- */

static void test_stream_paper(void **state)
{
    (void)state;
    int32_t moved = 0;
    assert_int_equal(scn_configure(ctx, 0), 0);
    assert_int_equal(scn_upload(ctx, paper, paper_size, 0), 0);
    assert_int_equal(scn_stream_compare(ctx, paper, paper_size, 0, 200, &moved), 0);
    assert_true(moved > 1000); /* corrections of more than 1 um went through */
    assert_int_equal(rd32(ctx, ABBE_MB_REG_ID_MODEL_CRC), table_crc(paper, paper_size));
}

static void test_stream_full_low_word_first(void **state)
{
    (void)state;
    int32_t moved = 0;
    assert_int_equal(modbus_write_register(ctx, ABBE_MB_REG_CT_WORD_ORDER, 1), 1);
    assert_int_equal(scn_configure(ctx, 1), 0);
    assert_int_equal(scn_upload(ctx, full, full_size, 1), 0);
    assert_int_equal(scn_stream_compare(ctx, full, full_size, 1, 200, &moved), 0);
    assert_true(moved > 10000);
    assert_int_equal(modbus_write_register(ctx, ABBE_MB_REG_CT_WORD_ORDER, 0), 1);
    assert_int_equal(rd32(ctx, ABBE_MB_REG_ID_MODEL_CRC), table_crc(full, full_size));
}

/* ---- uploads that must leave the running model alone ------------------------------------------- */

static uint32_t running_crc;

static void make_paper_run(void)
{
    assert_int_equal(mbt_upload(ctx, paper, paper_size, abbe_crc32(0, paper, paper_size), 120, 0), 0);
    one_cycle();
    running_crc = table_crc(paper, paper_size);
    assert_int_equal(rd32(ctx, ABBE_MB_REG_ID_MODEL_CRC), running_crc);
}

static void expect_untouched(int16_t result)
{
    assert_int_equal((int16_t)rd1(ctx, ABBE_MB_REG_UP_RESULT), result);
    assert_int_equal(rd1(ctx, ABBE_MB_REG_UP_STATE), ABBE_MB_UPLOAD_IDLE);
    one_cycle();
    assert_int_equal(rd32(ctx, ABBE_MB_REG_ID_MODEL_CRC), running_crc);
    assert_int_equal(rd32(ctx, ABBE_MB_REG_ID_PENDING_CRC), 0);
}

static void test_bad_upload_crc_and_format(void **state)
{
    (void)state;
    static uint8_t bad[ABBE_MB_STAGING_MAX];
    make_paper_run();
    uint32_t rejected = rd32(ctx, ABBE_MB_REG_ST_UPLOADS_REJECTED);

    /* commit CRC does not match what arrived */
    errno = 0;
    assert_int_equal(mbt_upload(ctx, full, full_size, abbe_crc32(0, full, full_size) ^ 0x80u, 123, 0), -1);
    assert_int_equal(errno, EMBXILVAL);
    expect_untouched(ABBE_MB_UP_CRC_MISMATCH);
    assert_int_equal(rd32(ctx, ABBE_MB_REG_UP_RX_CRC), abbe_crc32(0, full, full_size));

    /* arrives intact, fails the table checks: the library's status */
    memcpy(bad, full, full_size);
    bad[0] = 'Z';
    assert_int_equal(mbt_upload(ctx, bad, full_size, abbe_crc32(0, bad, full_size), 100, 0), -1);
    assert_int_equal(errno, EMBXILVAL);
    expect_untouched(ABBE_E_MAGIC);
    memcpy(bad, full, full_size);
    bad[3000] ^= 0x10;
    assert_int_equal(mbt_upload(ctx, bad, full_size, abbe_crc32(0, bad, full_size), 77, 0), -1);
    expect_untouched(ABBE_E_CRC);

    /* incomplete */
    assert_int_equal(mbt_upload_begin(ctx), 0);
    assert_int_equal(mbt_upload_chunk(ctx, full, 0, 246), 0);
    assert_int_equal(mbt_upload_commit(ctx, (uint32_t)full_size, abbe_crc32(0, full, full_size), 0), -1);
    assert_int_equal(errno, EMBXILVAL);
    expect_untouched(ABBE_MB_UP_INCOMPLETE);
    assert_int_equal(rd32(ctx, ABBE_MB_REG_ST_UPLOADS_REJECTED), rejected + 4);
}

static void test_bad_upload_interleaved_client(void **state)
{
    (void)state;
    make_paper_run();
    modbus_t *other = mbt_tcp_client(srv.port);
    assert_non_null(other);

    assert_int_equal(mbt_upload_begin(ctx), 0);
    assert_int_equal(mbt_upload_chunk(ctx, full, 0, 246), 0);
    /* the second client's begin, chunks and commit are refused: busy */
    assert_int_equal(mbt_upload_begin(other), -1);
    assert_int_equal(errno, EMBXSBUSY);
    assert_int_equal(mbt_upload_chunk(other, paper, 0, 246), -1);
    assert_int_equal(errno, EMBXSBUSY);
    assert_int_equal(mbt_upload_chunk(other, paper, 246, 246), -1);
    assert_int_equal(errno, EMBXSBUSY);
    assert_int_equal(mbt_upload_commit(other, (uint32_t)paper_size, abbe_crc32(0, paper, paper_size), 0), -1);
    assert_int_equal(errno, EMBXSBUSY);
    uint16_t staged[4];
    assert_int_equal(modbus_read_registers(other, ABBE_MB_REG_STAGING, 4, staged), -1);
    assert_int_equal(errno, EMBXSBUSY);
    /* the owner's upload is intact */
    for (size_t off = 246; off < full_size; off += 246) {
        assert_int_equal(mbt_upload_chunk(ctx, full, off, full_size - off < 246 ? full_size - off : 246), 0);
    }
    assert_int_equal(mbt_upload_commit(ctx, (uint32_t)full_size, abbe_crc32(0, full, full_size), 0), 0);
    one_cycle();
    assert_int_equal(rd32(other, ABBE_MB_REG_ID_MODEL_CRC), table_crc(full, full_size));
    modbus_close(other);
    modbus_free(other);
}

static void test_bad_upload_disconnect(void **state)
{
    (void)state;
    make_paper_run();
    modbus_t *other = mbt_tcp_client(srv.port);
    assert_non_null(other);
    assert_int_equal(mbt_upload_begin(other), 0);
    for (size_t off = 0; off < 3000; off += 246) {
        assert_int_equal(mbt_upload_chunk(other, full, off, 246), 0);
    }
    assert_int_equal(rd1(ctx, ABBE_MB_REG_UP_STATE), ABBE_MB_UPLOAD_OPEN);
    modbus_close(other); /* gone mid-upload */
    modbus_free(other);
    assert_int_equal(wait_reg(ctx, ABBE_MB_REG_UP_STATE, ABBE_MB_UPLOAD_IDLE), 0);
    expect_untouched(ABBE_MB_UP_DISCONNECTED);
    /* and the staging area is free again */
    assert_int_equal(mbt_upload(ctx, paper, paper_size, abbe_crc32(0, paper, paper_size), 123, 0), 0);
}

static void test_bad_upload_timeout(void **state)
{
    (void)state;
    make_paper_run();
    assert_int_equal(mbt_upload_begin(ctx), 0);
    assert_int_equal(mbt_upload_chunk(ctx, full, 0, 246), 0);
    /* the server was started with --upload-timeout-ms 300 */
    int i;
    for (i = 0; i < 200000 && rd1(ctx, ABBE_MB_REG_UP_STATE) != ABBE_MB_UPLOAD_IDLE; i++) {
    }
    assert_true(i < 200000);
    expect_untouched(ABBE_MB_UP_TIMEOUT);
}

/* ---- exception codes -------------------------------------------------------------------------- */

static void test_exception_codes(void **state)
{
    (void)state;
    static const struct {
        uint8_t pdu[16];
        int len;
        int ex;
    } cases[] = {
        {{0x01, 0, 0, 0, 1}, 5, 0x01},                           /* read coils: not supported */
        {{0x05, 0, 0, 0xFF, 0}, 5, 0x01},                        /* write coil */
        {{0x08, 0, 0, 0x12, 0x34}, 5, 0x01},                     /* diagnostics */
        {{0x16, 0x02, 0, 0xFF, 0xFF, 0, 0}, 7, 0x01},            /* mask write */
        {{0x2B, 0x0E, 1, 0}, 4, 0x01},                           /* device identification */
        {{0x03, 0, 0, 0, 0}, 5, 0x03},                           /* count 0 */
        {{0x03, 0, 0, 0, 126}, 5, 0x03},                         /* count 126 */
        {{0x03, 0, 0}, 3, 0x03},                                 /* truncated */
        {{0x03, 0, 0x14, 0, 1}, 5, 0x02},                        /* unmapped */
        {{0x04, 0x01, 0x1F, 0, 2}, 5, 0x02},                     /* straddles the end of a block */
        {{0x04, 0, 0, 0, 2}, 5, 0x00},                           /* FC04 reads the map */
        {{0x06, 0, 0, 0, 1}, 5, 0x02},                           /* read only */
        {{0x06, 0x02, 0x00, 0, 2}, 5, 0x03},                     /* ENABLE = 2 */
        {{0x06, 0x01, 0x00, 0, 1}, 5, 0x02},                     /* half of POS_X */
        {{0x10, 0x01, 0x00, 0, 1, 2, 0, 0}, 8, 0x02},            /* half of POS_X */
        {{0x10, 0x02, 0x00, 0, 1, 4, 0, 0, 0, 0}, 10, 0x03},     /* byte count mismatch */
        {{0x10, 0x02, 0x00, 0, 124, 2, 0, 0}, 8, 0x03},          /* count 124 */
        {{0x10, 0x10, 0x00, 0, 1, 2, 0, 0}, 8, 0x01},            /* staging without a session */
        {{0x17, 0x10, 0x00, 0, 1, 0x01, 0x0D, 0, 1, 2, 0, 1}, 12, 0x02}, /* FC23 on staging */
        {{0x17, 0x03, 0x00, 0, 1, 0x01, 0x0D, 0, 1, 2, 0, 1}, 12, 0x02}, /* FC23 read unmapped */
        {{0x17, 0x01, 0x20, 0, 0, 0x01, 0x0D, 0, 1, 2, 0, 1}, 12, 0x03}, /* FC23 read count 0 */
        {{0x17, 0x01, 0x20, 0, 1, 0x01, 0x0D, 0, 1, 4, 0, 1}, 12, 0x03}, /* FC23 byte count */
    };
    uint32_t cycles = rd32(ctx, ABBE_MB_REG_ST_CYCLES);
    uint32_t exceptions = rd32(ctx, ABBE_MB_REG_ST_EXCEPTIONS);
    int expected = 0;
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        int got = mbt_raw_exception(ctx, cases[i].pdu, cases[i].len);
        if (got != cases[i].ex) {
            fail_msg("case %zu (function 0x%02x): exception %d, want %d", i, cases[i].pdu[0], got, cases[i].ex);
        }
        expected += cases[i].ex != 0;
    }
    /* the refused FC23s ran no cycle */
    assert_int_equal(rd32(ctx, ABBE_MB_REG_ST_CYCLES), cycles);
    assert_int_equal(rd32(ctx, ABBE_MB_REG_ST_EXCEPTIONS), exceptions + (uint32_t)expected);
    assert_int_equal(rd1(ctx, ABBE_MB_REG_ST_LAST_EXCEPTION), 0x1703);
    /* and through the ordinary libmodbus calls */
    assert_int_equal(modbus_write_register(ctx, ABBE_MB_REG_ID_MAGIC, 1), -1);
    assert_int_equal(errno, EMBXILADD);
    uint16_t v[2];
    assert_int_equal(modbus_read_registers(ctx, 0x0FFF, 2, v), -1);
    assert_int_equal(errno, EMBXILADD);
}

/* ---- several clients, and clients that misbehave --------------------------------------------------- */

static void test_several_clients(void **state)
{
    (void)state;
    modbus_t *c[MAX_CLIENTS];
    uint32_t refused = rd32(ctx, ABBE_MB_REG_ST_CLIENTS_REFUSED);
    for (int i = 1; i < MAX_CLIENTS; i++) { /* ctx is the first */
        c[i] = mbt_tcp_client(srv.port);
        assert_non_null(c[i]);
        assert_int_equal(rd1(c[i], ABBE_MB_REG_ID_MAGIC), ABBE_MB_MAGIC_HI);
    }
    assert_int_equal(rd1(ctx, ABBE_MB_REG_ST_CLIENTS), MAX_CLIENTS);
    /* one more: accepted and closed at once */
    modbus_t *extra = mbt_tcp_client(srv.port);
    assert_non_null(extra);
    uint16_t v;
    assert_int_equal(modbus_read_registers(extra, 0, 1, &v), -1);
    modbus_close(extra);
    modbus_free(extra);
    assert_int_equal(rd32(ctx, ABBE_MB_REG_ST_CLIENTS_REFUSED), refused + 1);
    /* all four still served, interleaved */
    for (int k = 0; k < 20; k++) {
        for (int i = 1; i < MAX_CLIENTS; i++) {
            assert_int_equal(rd1(c[i], ABBE_MB_REG_ID_MAGIC + 1), ABBE_MB_MAGIC_LO);
        }
        assert_int_equal(rd1(ctx, ABBE_MB_REG_ID_MAGIC), ABBE_MB_MAGIC_HI);
    }
    /* a slot frees when a client leaves */
    modbus_close(c[1]);
    modbus_free(c[1]);
    assert_int_equal(wait_reg(ctx, ABBE_MB_REG_ST_CLIENTS, MAX_CLIENTS - 1), 0);
    c[1] = mbt_tcp_client(srv.port);
    assert_non_null(c[1]);
    assert_int_equal(rd1(c[1], ABBE_MB_REG_ID_MAGIC), ABBE_MB_MAGIC_HI);
    for (int i = 1; i < MAX_CLIENTS; i++) {
        modbus_close(c[i]);
        modbus_free(c[i]);
    }
    assert_int_equal(wait_reg(ctx, ABBE_MB_REG_ST_CLIENTS, 1), 0);
}

static int raw_connect(void)
{
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    struct sockaddr_in sa;
    memset(&sa, 0, sizeof sa);
    sa.sin_family = AF_INET;
    sa.sin_port = htons((uint16_t)srv.port);
    sa.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    assert_true(fd >= 0);
    assert_int_equal(connect(fd, (struct sockaddr *)&sa, sizeof sa), 0);
    return fd;
}

/* Wait up to 5 s for fd to become readable; return recv()'s result. */
static ssize_t raw_recv(int fd, uint8_t *buf, size_t cap)
{
    struct pollfd p = {fd, POLLIN, 0};
    if (poll(&p, 1, 5000) != 1) {
        return -2;
    }
    return recv(fd, buf, cap, 0);
}

static void test_half_request_blocks_nobody(void **state)
{
    (void)state;
    static const uint8_t req[12] = {0xAB, 0xCD, 0, 0, 0, 6, 1, 0x03, 0, 0, 0, 2};
    uint8_t rsp[64];
    int fd = raw_connect();
    assert_int_equal(send(fd, req, 5, 0), 5); /* half a header, then silence */
    for (int k = 0; k < 50; k++) {
        assert_int_equal(rd1(ctx, ABBE_MB_REG_ID_MAGIC), ABBE_MB_MAGIC_HI);
    }
    assert_int_equal(send(fd, req + 5, 7, 0), 7); /* the rest: answered */
    ssize_t n = raw_recv(fd, rsp, sizeof rsp);
    assert_int_equal(n, 13);
    assert_int_equal(rsp[0], 0xAB);
    assert_int_equal(rsp[1], 0xCD);
    assert_int_equal(rsp[9], 0x41);
    /* two requests in one segment: two answers */
    uint8_t two[24];
    memcpy(two, req, 12);
    memcpy(two + 12, req, 12);
    two[13] = 0xCE;
    assert_int_equal(send(fd, two, 24, 0), 24);
    size_t got = 0;
    while (got < 26) {
        n = raw_recv(fd, rsp + got, sizeof rsp - got);
        assert_true(n > 0);
        got += (size_t)n;
    }
    assert_int_equal(got, 26);
    assert_int_equal(rsp[13 + 1], 0xCE);
    /* not Modbus/TCP (protocol id 0x1234): the server hangs up */
    static const uint8_t junk[12] = {0, 1, 0x12, 0x34, 0, 6, 1, 3, 0, 0, 0, 1};
    assert_int_equal(send(fd, junk, sizeof junk, 0), 12);
    assert_int_equal(raw_recv(fd, rsp, sizeof rsp), 0);
    close(fd);
}

static void test_client_not_reading_blocks_nobody(void **state)
{
    (void)state;
    /* 125-register reads answered with 259 bytes each, never read: the
     * server's sends fail once the socket buffers are full and it drops this
     * client instead of waiting for it. */
    static const uint8_t req[12] = {0, 1, 0, 0, 0, 6, 1, 0x03, 0x10, 0x00, 0, 125};
    int fd = raw_connect();
    int opened = 0, rc = 0;
    uint8_t burst[12 * 64];
    for (int i = 0; i < 64; i++) {
        memcpy(burst + 12 * i, req, 12);
    }
    /* staging reads need a session: make one for this raw client */
    static const uint8_t begin[12] = {0, 2, 0, 0, 0, 6, 1, 0x06, 0, 0x50, 0, 1};
    uint8_t rsp[16];
    assert_int_equal(send(fd, begin, 12, 0), 12);
    assert_int_equal(raw_recv(fd, rsp, sizeof rsp), 12);
    opened = 1;
    int rounds;
    for (rounds = 0; rounds < 20000; rounds++) {
        rc = (int)send(fd, burst, sizeof burst, MSG_NOSIGNAL);
        if (rc < 0) {
            break; /* EPIPE / ECONNRESET: the server dropped us */
        }
        if ((rounds & 63) == 0) {
            assert_int_equal(rd1(ctx, ABBE_MB_REG_ID_MAGIC), ABBE_MB_MAGIC_HI); /* others are served */
        }
    }
    assert_true(rc < 0);
    assert_true(opened);
    close(fd);
    /* its upload session was dropped with it */
    assert_int_equal(wait_reg(ctx, ABBE_MB_REG_UP_STATE, ABBE_MB_UPLOAD_IDLE), 0);
    assert_int_equal((int16_t)rd1(ctx, ABBE_MB_REG_UP_RESULT), ABBE_MB_UP_DISCONNECTED);
    assert_int_equal(wait_reg(ctx, ABBE_MB_REG_ST_CLIENTS, 1), 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_identity),
        cmocka_unit_test(test_stream_paper),
        cmocka_unit_test(test_stream_full_low_word_first),
        cmocka_unit_test(test_bad_upload_crc_and_format),
        cmocka_unit_test(test_bad_upload_interleaved_client),
        cmocka_unit_test(test_bad_upload_disconnect),
        cmocka_unit_test(test_bad_upload_timeout),
        cmocka_unit_test(test_exception_codes),
        cmocka_unit_test(test_several_clients),
        cmocka_unit_test(test_half_request_blocks_nobody),
        cmocka_unit_test(test_client_not_reading_blocks_nobody),
    };
    return cmocka_run_group_tests_name("modbus_tcp", tests, group_setup, group_teardown);
}
