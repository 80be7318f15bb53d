/* Register map engine (abbe_mb_regs_*), called directly: every exception
 * path, the upload protocol and its failure modes, word order, the cycle. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "abbe/modbus_port.h"
#include "golden_data.h"
#include "harness.h"

static abbe_mb_regs_t R;
static uint8_t paper[ABBE_MB_STAGING_MAX];
static size_t paper_size;

#define A 1u /* connection tokens */
#define B 2u

static const uint8_t *full_blob(size_t *size)
{
    *size = 0;
    for (uint32_t i = 0; i < abbe_golden_table_count; i++) {
        if (strcmp(abbe_golden_tables[i].name, "full") == 0) {
            *size = abbe_golden_tables[i].blob_size;
            return abbe_golden_tables[i].blob;
        }
    }
    fail_msg("golden table 'full' missing");
    return NULL;
}

static int setup(void **state)
{
    (void)state;
    abbe_mb_regs_config_t cfg;
    abbe_mb_regs_default_config(&cfg);
    cfg.upload_timeout_ms = 1000;
    assert_int_equal(abbe_mb_regs_init(&R, &cfg, NULL, 0), ABBE_OK);
    abbe_mb_regs_tick(&R, 5000);
    return 0;
}

/* Write host-order registers. */
static int wr(uint32_t conn, uint16_t addr, uint16_t count, const uint16_t *v)
{
    uint8_t be[2 * 130];
    for (uint16_t i = 0; i < count; i++) {
        be[2 * i] = (uint8_t)(v[i] >> 8);
        be[2 * i + 1] = (uint8_t)(v[i] & 0xFFu);
    }
    return abbe_mb_regs_write(&R, conn, addr, count, be);
}

static int wr1(uint32_t conn, uint16_t addr, uint16_t v)
{
    return wr(conn, addr, 1, &v);
}

static uint16_t rd1(uint16_t addr)
{
    uint16_t v = 0xDEAD;
    assert_int_equal(abbe_mb_regs_read(&R, A, addr, 1, &v), 0);
    return v;
}

static uint32_t rd32(uint16_t addr)
{
    uint16_t v[2];
    assert_int_equal(abbe_mb_regs_read(&R, A, addr, 2, v), 0);
    return mbt_get32(v, R.word_order);
}

static int begin(uint32_t conn)
{
    return wr1(conn, ABBE_MB_REG_UP_CMD, ABBE_MB_UP_CMD_BEGIN);
}

static int chunk(uint32_t conn, const uint8_t *blob, size_t off, size_t len)
{
    return abbe_mb_regs_write(&R, conn, (uint16_t)(ABBE_MB_REG_STAGING + off / 2), (uint16_t)((len + 1) / 2),
                              blob + off);
}

static int send_all(uint32_t conn, const uint8_t *blob, size_t len)
{
    for (size_t off = 0; off < len; off += 240) {
        int ex = chunk(conn, blob, off, len - off < 240 ? len - off : 240);
        if (ex != 0) {
            return ex;
        }
    }
    return 0;
}

static int commit(uint32_t conn, uint32_t len, uint32_t crc)
{
    uint16_t v[4];
    mbt_put32(&v[0], len, R.word_order);
    mbt_put32(&v[2], crc, R.word_order);
    return wr(conn, ABBE_MB_REG_UP_COMMIT, 4, v);
}

static int upload(uint32_t conn, const uint8_t *blob, size_t len)
{
    int ex = begin(conn);
    if (ex == 0) {
        ex = send_all(conn, blob, len);
    }
    return ex != 0 ? ex : commit(conn, (uint32_t)len, abbe_crc32(0, blob, len));
}

static void cycle(void)
{
    assert_int_equal(wr1(A, ABBE_MB_REG_IN_CYCLE, 1), 0);
}

static uint32_t table_crc(const uint8_t *blob, size_t len)
{
    abbe_model_t m;
    assert_int_equal(abbe_model_load(&m, blob, len), ABBE_OK);
    return abbe_model_crc(&m);
}

/* ---- identity, word order ------------------------------------------------------ */

static void test_identity(void **state)
{
    (void)state;
    uint16_t id[ABBE_MB_ID_COUNT];
    assert_int_equal(abbe_mb_regs_read(&R, A, 0, ABBE_MB_ID_COUNT, id), 0);
    assert_int_equal(id[0], 0x4142);
    assert_int_equal(id[1], 0x4245);
    assert_int_equal(id[ABBE_MB_REG_ID_REGMAP], ABBE_MB_REGMAP_VERSION);
    assert_int_equal(id[ABBE_MB_REG_ID_LIB_MAJOR], ABBE_VERSION_MAJOR);
    assert_int_equal(id[ABBE_MB_REG_ID_LIB_MINOR], ABBE_VERSION_MINOR);
    assert_int_equal(id[ABBE_MB_REG_ID_FMT_MAJOR], ABBE_TABLE_FORMAT_MAJOR);
    assert_int_equal(id[ABBE_MB_REG_ID_SELFTEST], 0x1234);
    assert_int_equal(id[ABBE_MB_REG_ID_SELFTEST + 1], 0x5678);
    assert_int_equal(rd32(ABBE_MB_REG_ID_MODEL_CRC), 0);
    assert_int_equal(rd32(ABBE_MB_REG_ID_STAGING_MAX), ABBE_MB_STAGING_MAX);

    /* low word first: the self-test shows it, every pair follows */
    assert_int_equal(wr1(A, ABBE_MB_REG_CT_WORD_ORDER, ABBE_MB_WORD_ORDER_LOW_FIRST), 0);
    assert_int_equal(rd1(ABBE_MB_REG_ID_SELFTEST), 0x5678);
    assert_int_equal(rd1(ABBE_MB_REG_ID_SELFTEST + 1), 0x1234);
    assert_int_equal(rd1(ABBE_MB_REG_ID_STAGING_MAX), ABBE_MB_STAGING_MAX & 0xFFFF);
    uint16_t pos[2] = {0x5678, 0xFFFF}; /* -43400 nm = 0xFFFF5678 low first */
    assert_int_equal(wr(A, ABBE_MB_REG_IN_POS_Y, 2, pos), 0);
    assert_int_equal((int32_t)rd32(ABBE_MB_REG_IN_POS_Y), (int32_t)0xFFFF5678u);
    assert_int_equal(wr1(A, ABBE_MB_REG_CT_WORD_ORDER, 2), ABBE_MB_EX_ILLEGAL_VALUE);
    assert_int_equal(wr1(A, ABBE_MB_REG_CT_WORD_ORDER, ABBE_MB_WORD_ORDER_HIGH_FIRST), 0);
    assert_int_equal((int32_t)rd32(ABBE_MB_REG_IN_POS_Y), (int32_t)0xFFFF5678u);
}

/* ---- exception codes ---------------------------------------------------------------- */

static void test_read_exceptions(void **state)
{
    (void)state;
    uint16_t v[130];
    assert_int_equal(abbe_mb_regs_read(&R, A, 0, 0, v), ABBE_MB_EX_ILLEGAL_VALUE);
    assert_int_equal(abbe_mb_regs_read(&R, A, 0, 126, v), ABBE_MB_EX_ILLEGAL_VALUE);
    assert_int_equal(abbe_mb_regs_read(&R, A, ABBE_MB_ID_COUNT, 1, v), ABBE_MB_EX_ILLEGAL_ADDRESS);
    assert_int_equal(abbe_mb_regs_read(&R, A, 0, ABBE_MB_ID_COUNT + 1, v), ABBE_MB_EX_ILLEGAL_ADDRESS);
    assert_int_equal(abbe_mb_regs_read(&R, A, 0x0100, 0x30, v), ABBE_MB_EX_ILLEGAL_ADDRESS); /* in..out gap */
    assert_int_equal(abbe_mb_regs_read(&R, A, 0x0FFF, 2, v), ABBE_MB_EX_ILLEGAL_ADDRESS);
    assert_int_equal(abbe_mb_regs_read(&R, A, 0xFFFF, 1, v), ABBE_MB_EX_ILLEGAL_ADDRESS);
    assert_int_equal(abbe_mb_regs_read(&R, A, (uint16_t)(ABBE_MB_REG_STAGING + ABBE_MB_STAGING_MAX / 2 - 1), 2, v),
                     ABBE_MB_EX_ILLEGAL_ADDRESS);
    /* staging without a session: wrong state; someone else's: busy */
    assert_int_equal(abbe_mb_regs_read(&R, A, ABBE_MB_REG_STAGING, 4, v), ABBE_MB_EX_ILLEGAL_FUNCTION);
    assert_int_equal(begin(B), 0);
    assert_int_equal(abbe_mb_regs_read(&R, A, ABBE_MB_REG_STAGING, 4, v), ABBE_MB_EX_BUSY);
    assert_int_equal(abbe_mb_regs_read(&R, B, ABBE_MB_REG_STAGING, 4, v), 0);
    /* the whole of every block reads */
    assert_int_equal(abbe_mb_regs_read(&R, A, ABBE_MB_REG_ST_BASE, ABBE_MB_ST_COUNT, v), 0);
    assert_int_equal(abbe_mb_regs_read(&R, A, ABBE_MB_REG_UP_BASE, ABBE_MB_UP_COUNT, v), 0);
    assert_int_equal(abbe_mb_regs_read(&R, A, ABBE_MB_REG_IN_BASE, ABBE_MB_IN_COUNT, v), 0);
    assert_int_equal(abbe_mb_regs_read(&R, A, ABBE_MB_REG_OUT_BASE, ABBE_MB_OUT_COUNT, v), 0);
    assert_int_equal(abbe_mb_regs_read(&R, A, ABBE_MB_REG_CT_BASE, ABBE_MB_CT_COUNT, v), 0);
}

static void test_write_exceptions(void **state)
{
    (void)state;
    uint16_t v[124] = {0};
    /* read-only and unmapped */
    assert_int_equal(wr1(A, ABBE_MB_REG_ID_MAGIC, 1), ABBE_MB_EX_ILLEGAL_ADDRESS);
    assert_int_equal(wr1(A, ABBE_MB_REG_ST_STATE, 1), ABBE_MB_EX_ILLEGAL_ADDRESS);
    assert_int_equal(wr1(A, ABBE_MB_REG_OUT_CORR_X, 1), ABBE_MB_EX_ILLEGAL_ADDRESS);
    assert_int_equal(wr1(A, ABBE_MB_REG_UP_STATE, 1), ABBE_MB_EX_ILLEGAL_ADDRESS);
    assert_int_equal(wr1(A, 0x0300, 1), ABBE_MB_EX_ILLEGAL_ADDRESS);
    /* counts */
    assert_int_equal(wr(A, ABBE_MB_REG_IN_BASE, 0, v), ABBE_MB_EX_ILLEGAL_VALUE);
    assert_int_equal(wr(A, ABBE_MB_REG_STAGING, 124, v), ABBE_MB_EX_ILLEGAL_VALUE);
    /* half of a 32-bit value, at either end */
    assert_int_equal(wr(A, ABBE_MB_REG_IN_POS_X, 1, v), ABBE_MB_EX_ILLEGAL_ADDRESS);
    assert_int_equal(wr(A, ABBE_MB_REG_IN_POS_X + 1, 2, v), ABBE_MB_EX_ILLEGAL_ADDRESS);
    assert_int_equal(wr(A, ABBE_MB_REG_IN_POS_Z + 1, 2, v), ABBE_MB_EX_ILLEGAL_ADDRESS);
    assert_int_equal(wr(A, ABBE_MB_REG_CT_STALE_CYCLES, 2, v), ABBE_MB_EX_ILLEGAL_ADDRESS);
    assert_int_equal(wr(A, ABBE_MB_REG_UP_COMMIT, 2, v), ABBE_MB_EX_ILLEGAL_ADDRESS);
    assert_int_equal(wr(A, ABBE_MB_REG_UP_CMD, 2, v), ABBE_MB_EX_ILLEGAL_ADDRESS);
    /* values */
    assert_int_equal(wr1(A, ABBE_MB_REG_IN_DIR_Y, 2), ABBE_MB_EX_ILLEGAL_VALUE);
    assert_int_equal(wr1(A, ABBE_MB_REG_IN_DIR_Y, 0xFFFE), ABBE_MB_EX_ILLEGAL_VALUE);
    assert_int_equal(wr1(A, ABBE_MB_REG_IN_DIR_Y, 0xFFFF), 0);
    assert_int_equal(wr1(A, ABBE_MB_REG_IN_AXIS_FAULT, 8), ABBE_MB_EX_ILLEGAL_VALUE);
    assert_int_equal(wr1(A, ABBE_MB_REG_CT_ENABLE, 2), ABBE_MB_EX_ILLEGAL_VALUE);
    assert_int_equal(wr1(A, ABBE_MB_REG_CT_RESET, 7), ABBE_MB_EX_ILLEGAL_VALUE);
    assert_int_equal(wr1(A, ABBE_MB_REG_CT_DIR_SOURCE, 2), ABBE_MB_EX_ILLEGAL_VALUE);
    assert_int_equal(wr1(A, ABBE_MB_REG_CT_SIGN_X, 0), ABBE_MB_EX_ILLEGAL_VALUE);
    assert_int_equal(wr1(A, ABBE_MB_REG_CT_FADE_CYCLES, 0), ABBE_MB_EX_ILLEGAL_VALUE);
    assert_int_equal(wr1(A, ABBE_MB_REG_UP_CMD, 3), ABBE_MB_EX_ILLEGAL_VALUE);
    /* limit below warn: refused as a whole, nothing changes */
    uint32_t warn = rd32(ABBE_MB_REG_CT_WARN_X);
    uint16_t bad[8] = {0, 1, 0, 1, 0, 1, 0, 0}; /* warn X..Z = 1 nm, then limit X = 0 */
    assert_int_equal(wr(A, ABBE_MB_REG_CT_WARN_X, 8, bad), ABBE_MB_EX_ILLEGAL_VALUE);
    assert_int_equal(rd32(ABBE_MB_REG_CT_WARN_X), warn);
    /* a rejected input write changes nothing either (pos valid, dir invalid) */
    uint16_t in[7] = {0, 77, 0, 0, 0, 0, 5};
    int32_t before = (int32_t)rd32(ABBE_MB_REG_IN_POS_X);
    assert_int_equal(wr(A, ABBE_MB_REG_IN_POS_X, 7, in), ABBE_MB_EX_ILLEGAL_VALUE);
    assert_int_equal((int32_t)rd32(ABBE_MB_REG_IN_POS_X), before);
}

static void test_limits_only_when_off(void **state)
{
    (void)state;
    uint16_t fade = 7;
    assert_int_equal(wr1(A, ABBE_MB_REG_CT_ENABLE, 1), 0);
    assert_int_equal(wr(A, ABBE_MB_REG_CT_FADE_CYCLES, 1, &fade), ABBE_MB_EX_ILLEGAL_FUNCTION);
    assert_int_equal(wr1(A, ABBE_MB_REG_CT_ENABLE, 0), 0);
    cycle();
    assert_int_equal(wr(A, ABBE_MB_REG_CT_FADE_CYCLES, 1, &fade), 0);
    assert_int_equal(rd1(ABBE_MB_REG_CT_FADE_CYCLES), 7);
    /* limits + enable in one request: configured, then enabled */
    uint16_t blk[5] = {1, 0, 0, 0, 9};
    assert_int_equal(wr(A, ABBE_MB_REG_CT_ENABLE, 5, blk), 0);
    assert_int_equal(rd1(ABBE_MB_REG_CT_FADE_CYCLES), 9);
    assert_int_equal(rd1(ABBE_MB_REG_CT_ENABLE), 1);
}

/* ---- upload ----------------------------------------------------------------------------- */

static void test_upload_ok_and_swap_at_cycle(void **state)
{
    (void)state;
    uint32_t crc = table_crc(paper, paper_size);
    assert_int_equal(upload(A, paper, paper_size), 0);
    assert_int_equal((int16_t)rd1(ABBE_MB_REG_UP_RESULT), ABBE_MB_UP_OK);
    assert_int_equal(rd1(ABBE_MB_REG_UP_STATE), ABBE_MB_UPLOAD_IDLE);
    assert_int_equal(rd32(ABBE_MB_REG_UP_MODEL_CRC), crc);
    assert_int_equal(rd32(ABBE_MB_REG_UP_RX_CRC), abbe_crc32(0, paper, paper_size));
    assert_int_equal(rd32(ABBE_MB_REG_ID_PENDING_CRC), crc);
    assert_int_equal(rd32(ABBE_MB_REG_ID_MODEL_CRC), 0); /* not before a cycle boundary */
    assert_int_equal(rd32(ABBE_MB_REG_ST_UPLOADS_OK), 1);
    cycle();
    assert_int_equal(rd32(ABBE_MB_REG_ID_MODEL_CRC), crc);
    assert_int_equal(rd32(ABBE_MB_REG_ID_MODEL_SIZE), paper_size);
    assert_int_equal(rd32(ABBE_MB_REG_ID_PENDING_CRC), 0);
    assert_int_equal(rd32(ABBE_MB_REG_ST_MODEL_SWAPS), 1);
    assert_true(rd1(ABBE_MB_REG_OUT_FLAGS) & ABBE_FLAG_MODEL_SWAPPED);

    /* a second table while one runs, then a third before any cycle: the
     * latest queued one wins, the running one is untouched until then */
    size_t fsize;
    const uint8_t *full = full_blob(&fsize);
    assert_int_equal(upload(A, full, fsize), 0);
    assert_int_equal(upload(B, paper, paper_size), 0);
    assert_int_equal(rd32(ABBE_MB_REG_ID_MODEL_CRC), crc);
    assert_int_equal(rd32(ABBE_MB_REG_ID_PENDING_CRC), crc);
    assert_int_equal(upload(A, full, fsize), 0);
    cycle();
    assert_int_equal(rd32(ABBE_MB_REG_ID_MODEL_CRC), table_crc(full, fsize));
    assert_int_equal(rd32(ABBE_MB_REG_ST_UPLOADS_OK), 4);
    assert_int_equal(rd32(ABBE_MB_REG_ST_UPLOADS_REJECTED), 0);
}

/* Run one failing upload against a running paper model and check the result
 * code, the counter, and that the running model is untouched. */
static void expect_refused(int ex_got, int ex_want, int16_t result)
{
    assert_int_equal(ex_got, ex_want);
    assert_int_equal((int16_t)rd1(ABBE_MB_REG_UP_RESULT), result);
    assert_int_equal(rd1(ABBE_MB_REG_UP_STATE), ABBE_MB_UPLOAD_IDLE);
    cycle();
    assert_int_equal(rd32(ABBE_MB_REG_ID_MODEL_CRC), table_crc(paper, paper_size));
    assert_int_equal(rd32(ABBE_MB_REG_ID_PENDING_CRC), 0);
}

static void running_paper(void)
{
    assert_int_equal(upload(A, paper, paper_size), 0);
    cycle();
    assert_int_equal(rd32(ABBE_MB_REG_ID_MODEL_CRC), table_crc(paper, paper_size));
}

static void test_upload_refused(void **state)
{
    (void)state;
    size_t fsize;
    const uint8_t *full = full_blob(&fsize);
    static uint8_t bad[ABBE_MB_STAGING_MAX];
    running_paper();

    /* transfer CRC mismatch */
    assert_int_equal(begin(A), 0);
    assert_int_equal(send_all(A, full, fsize), 0);
    expect_refused(commit(A, (uint32_t)fsize, abbe_crc32(0, full, fsize) ^ 1u), ABBE_MB_EX_ILLEGAL_VALUE,
                   ABBE_MB_UP_CRC_MISMATCH);

    /* a byte damaged in transit (the commit carries the sender's CRC) */
    memcpy(bad, full, fsize);
    bad[1000] ^= 0x40;
    assert_int_equal(begin(A), 0);
    assert_int_equal(send_all(A, bad, fsize), 0);
    expect_refused(commit(A, (uint32_t)fsize, abbe_crc32(0, full, fsize)), ABBE_MB_EX_ILLEGAL_VALUE,
                   ABBE_MB_UP_CRC_MISMATCH);

    /* transfer intact but the table is not: format checks, their status */
    memcpy(bad, full, fsize);
    bad[0] = 'X';
    expect_refused(upload(A, bad, fsize), ABBE_MB_EX_ILLEGAL_VALUE, ABBE_E_MAGIC);
    memcpy(bad, full, fsize);
    bad[2000] ^= 1u; /* the table's own CRC no longer matches */
    expect_refused(upload(A, bad, fsize), ABBE_MB_EX_ILLEGAL_VALUE, ABBE_E_CRC);
    expect_refused(upload(A, full, fsize - 4), ABBE_MB_EX_ILLEGAL_VALUE, ABBE_E_TRUNCATED);
    memcpy(bad, full, fsize);
    bad[4] = 2; /* format major 2 */
    expect_refused(upload(A, bad, fsize), ABBE_MB_EX_ILLEGAL_VALUE, ABBE_E_VERSION_MAJOR);
    /* a float32 coefficient that is not its int32 twin: -17, a library status
     * like the others (UP_RESULT -1..-99) */
    long mlen = mbt_read_file(ABBE_MISMATCH_MODEL, bad, sizeof bad);
    assert_true(mlen > 64);
    uint32_t total = (uint32_t)bad[8] | (uint32_t)bad[9] << 8 | (uint32_t)bad[10] << 16 | (uint32_t)bad[11] << 24;
    assert_true(total >= 64u && total <= (uint32_t)mlen);
    uint32_t tcrc = abbe_crc32(0, bad, total - 4u); /* the fuzzer found it with its CRC fixed up */
    for (unsigned k = 0; k < 4u; k++) {
        bad[total - 4u + k] = (uint8_t)(tcrc >> (8u * k));
    }
    expect_refused(upload(A, bad, (size_t)mlen), ABBE_MB_EX_ILLEGAL_VALUE, ABBE_E_MISMATCH);

    /* incomplete: commit claims more than was received */
    assert_int_equal(begin(A), 0);
    assert_int_equal(send_all(A, full, 2400), 0);
    assert_int_equal(rd32(ABBE_MB_REG_UP_FILLED), 2400);
    expect_refused(commit(A, (uint32_t)fsize, abbe_crc32(0, full, fsize)), ABBE_MB_EX_ILLEGAL_VALUE,
                   ABBE_MB_UP_INCOMPLETE);

    /* length 0 and over the staging size */
    assert_int_equal(begin(A), 0);
    expect_refused(commit(A, 0, 0), ABBE_MB_EX_ILLEGAL_VALUE, ABBE_MB_UP_LENGTH);
    assert_int_equal(begin(A), 0);
    expect_refused(commit(A, ABBE_MB_STAGING_MAX + 4u, 0), ABBE_MB_EX_ILLEGAL_VALUE, ABBE_MB_UP_LENGTH);

    /* chunks must not leave a gap; writes past the staging area are unmapped */
    assert_int_equal(begin(A), 0);
    assert_int_equal(chunk(A, full, 0, 240), 0);
    assert_int_equal(chunk(A, full, 480, 240), ABBE_MB_EX_ILLEGAL_ADDRESS);
    assert_int_equal(chunk(A, full, 0, 240), 0); /* a retried chunk is fine */
    assert_int_equal(abbe_mb_regs_write(&R, A, (uint16_t)(ABBE_MB_REG_STAGING + ABBE_MB_STAGING_MAX / 2 - 1), 2,
                                        full),
                     ABBE_MB_EX_ILLEGAL_ADDRESS);
    /* abort */
    expect_refused(wr1(A, ABBE_MB_REG_UP_CMD, ABBE_MB_UP_CMD_ABORT), 0, ABBE_MB_UP_ABORTED);
    assert_int_equal(wr1(A, ABBE_MB_REG_UP_CMD, ABBE_MB_UP_CMD_ABORT), ABBE_MB_EX_ILLEGAL_FUNCTION);

    /* no session: staging writes and commits are refused (wrong state) */
    assert_int_equal(chunk(A, full, 0, 240), ABBE_MB_EX_ILLEGAL_FUNCTION);
    assert_int_equal(commit(A, (uint32_t)fsize, 0), ABBE_MB_EX_ILLEGAL_FUNCTION);
    assert_int_equal(rd32(ABBE_MB_REG_ID_MODEL_CRC), table_crc(paper, paper_size));
    /* every refused or lost session counted once: CRC x2, format x5,
     * incomplete, length x2, abort */
    assert_int_equal(rd32(ABBE_MB_REG_ST_UPLOADS_REJECTED), 11);
    assert_int_equal(rd32(ABBE_MB_REG_ST_UPLOADS_OK), 1);
}

static void test_upload_second_client(void **state)
{
    (void)state;
    size_t fsize;
    const uint8_t *full = full_blob(&fsize);
    running_paper();
    uint16_t session;

    assert_int_equal(begin(A), 0);
    session = rd1(ABBE_MB_REG_UP_SESSION);
    assert_int_equal(send_all(A, full, 2400), 0);
    /* B interleaves: begin, chunk, commit, abort are all refused as busy */
    assert_int_equal(begin(B), ABBE_MB_EX_BUSY);
    assert_int_equal(chunk(B, paper, 0, 240), ABBE_MB_EX_BUSY);
    assert_int_equal(chunk(B, paper, 2400, 240), ABBE_MB_EX_BUSY);
    assert_int_equal(commit(B, (uint32_t)paper_size, abbe_crc32(0, paper, paper_size)), ABBE_MB_EX_BUSY);
    assert_int_equal(wr1(B, ABBE_MB_REG_UP_CMD, ABBE_MB_UP_CMD_ABORT), ABBE_MB_EX_BUSY);
    assert_int_equal(rd32(ABBE_MB_REG_ST_UPLOADS_REJECTED), 1);
    assert_int_equal(rd1(ABBE_MB_REG_UP_SESSION), session);
    /* A's upload is intact and completes */
    assert_int_equal(send_all(A, full, fsize), 0);
    assert_int_equal(commit(A, (uint32_t)fsize, abbe_crc32(0, full, fsize)), 0);
    cycle();
    assert_int_equal(rd32(ABBE_MB_REG_ID_MODEL_CRC), table_crc(full, fsize));
    /* now B may */
    assert_int_equal(upload(B, paper, paper_size), 0);
    assert_int_equal(rd1(ABBE_MB_REG_UP_SESSION), (uint16_t)(session + 1));
}

static void test_upload_disconnect_and_timeout(void **state)
{
    (void)state;
    size_t fsize;
    const uint8_t *full = full_blob(&fsize);
    running_paper();

    assert_int_equal(begin(A), 0);
    assert_int_equal(send_all(A, full, fsize), 0);
    abbe_mb_regs_disconnect(&R, B); /* someone else leaving changes nothing */
    assert_int_equal(rd1(ABBE_MB_REG_UP_STATE), ABBE_MB_UPLOAD_OPEN);
    abbe_mb_regs_disconnect(&R, A);
    expect_refused(0, 0, ABBE_MB_UP_DISCONNECTED);
    assert_int_equal(commit(A, (uint32_t)fsize, abbe_crc32(0, full, fsize)), ABBE_MB_EX_ILLEGAL_FUNCTION);

    /* idle timeout (1000 ms in setup): activity keeps it open */
    assert_int_equal(begin(A), 0);
    abbe_mb_regs_tick(&R, 5900);
    assert_int_equal(chunk(A, full, 0, 240), 0);
    abbe_mb_regs_tick(&R, 6800);
    assert_int_equal(rd1(ABBE_MB_REG_UP_STATE), ABBE_MB_UPLOAD_OPEN);
    abbe_mb_regs_tick(&R, 6900);
    expect_refused(0, 0, ABBE_MB_UP_TIMEOUT);
    assert_int_equal(rd32(ABBE_MB_REG_ST_UPLOADS_REJECTED), 2);
}

/* ---- the cycle ---------------------------------------------------------------------------- */

static void test_cycle_trigger_and_fresh(void **state)
{
    (void)state;
    running_paper();
    uint16_t in[ABBE_MB_IN_COUNT] = {0};
    mbt_put32(&in[0], 100000000u, 0);
    mbt_put32(&in[2], (uint32_t)-100000000, 0);
    mbt_put32(&in[4], (uint32_t)-100000000, 0);
    in[13] = 41;
    uint32_t cycles = rd32(ABBE_MB_REG_ST_CYCLES);
    /* positions without the cycle register: no cycle */
    assert_int_equal(wr(A, ABBE_MB_REG_IN_BASE, 6, in), 0);
    assert_int_equal(rd32(ABBE_MB_REG_ST_CYCLES), cycles);
    /* the whole block: one cycle, fresh */
    assert_int_equal(wr(A, ABBE_MB_REG_IN_BASE, ABBE_MB_IN_COUNT, in), 0);
    assert_int_equal(rd32(ABBE_MB_REG_ST_CYCLES), cycles + 1);
    assert_int_equal(rd1(ABBE_MB_REG_OUT_CYCLE), 41);
    assert_false(rd1(ABBE_MB_REG_OUT_FLAGS) & ABBE_FLAG_INPUT_INVALID);
    assert_true(rd32(ABBE_MB_REG_OUT_ERR_X) != 0u);
    /* only X and Z positions, then cycle: not fresh */
    uint32_t invalid = rd32(ABBE_MB_REG_ST_INVALID_INPUTS);
    assert_int_equal(wr(A, ABBE_MB_REG_IN_POS_X, 2, &in[0]), 0);
    assert_int_equal(wr(A, ABBE_MB_REG_IN_POS_Z, 2, &in[4]), 0);
    cycle();
    assert_true(rd1(ABBE_MB_REG_OUT_FLAGS) & ABBE_FLAG_INPUT_INVALID);
    assert_int_equal(rd32(ABBE_MB_REG_ST_INVALID_INPUTS), invalid + 1);
    /* stale after stale_cycles (10 by default) */
    for (int k = 0; k < 10; k++) {
        cycle();
    }
    assert_true(rd1(ABBE_MB_REG_ST_FLAGS) & ABBE_FLAG_STALE);
    assert_int_equal(rd32(ABBE_MB_REG_ST_STALE_EVENTS), 1);
}

/* Direction from the position change (CT_DIR_SOURCE = 1) equals writing the
 * sign into IN_DIR: compare against a local compensator. */
static void test_dir_from_position(void **state)
{
    (void)state;
    size_t fsize;
    const uint8_t *full = full_blob(&fsize);
    abbe_comp_t local;
    abbe_model_t slot;
    abbe_mb_regs_config_t cfg;
    abbe_mb_regs_default_config(&cfg);
    cfg.dir_source = 1;
    cfg.comp.fade_cycles = 2;
    for (int j = 0; j < 3; j++) {
        cfg.comp.warn_nm[j] = 100000000;
        cfg.comp.limit_nm[j] = 200000000;
        cfg.comp.rate_nm_per_cycle[j] = 100000000;
    }
    assert_int_equal(abbe_mb_regs_init(&R, &cfg, full, fsize), ABBE_OK);
    assert_int_equal(abbe_comp_init(&local, &cfg.comp, NULL), ABBE_OK);
    assert_int_equal(abbe_comp_load_model(&local, &slot, full, fsize), ABBE_OK);
    assert_int_equal(wr1(A, ABBE_MB_REG_CT_ENABLE, 1), 0);
    assert_int_equal(abbe_comp_enable(&local), ABBE_OK);
    int32_t prev[3] = {0, 0, 0};
    int have = 0;
    for (int k = 0; k < 60; k++) {
        int32_t p[3] = {500000000 + 40000 * ((k % 20) < 10 ? k % 10 : 10 - k % 10),
                        -700000000 - 25000 * (k % 7), -300000000 + 1000 * k};
        uint16_t in[ABBE_MB_IN_COUNT] = {0};
        abbe_comp_input_q_t li;
        abbe_comp_output_t lo;
        memset(&li, 0, sizeof li);
        for (int j = 0; j < 3; j++) {
            mbt_put32(&in[2 * j], (uint32_t)p[j], 0);
            in[9 + j] = 2150;
            li.pos_nm[j] = p[j];
            li.temp_mdegc[j] = 21500;
            li.dir[j] = (int8_t)(!have ? 0 : (p[j] > prev[j] ? 1 : (p[j] < prev[j] ? -1 : 0)));
        }
        li.fresh = 1;
        in[6] = 1; /* ignored with CT_DIR_SOURCE = 1 */
        assert_int_equal(wr(A, ABBE_MB_REG_IN_BASE, ABBE_MB_IN_COUNT, in), 0);
        assert_int_equal(abbe_comp_step_q(&local, &li, &lo), ABBE_OK);
        for (int j = 0; j < 3; j++) {
            assert_int_equal((int32_t)rd32((uint16_t)(ABBE_MB_REG_OUT_CORR_X + 2 * j)), lo.corr_nm[j]);
        }
        memcpy(prev, p, sizeof prev);
        have = 1;
    }
}

/* IN_TEMP_* feed the thermal term (the full table has one on every axis):
 * every cycle equals a local compensator given the same temperatures; 0x8000
 * keeps an axis' temperature; a value outside -50..150 degC is exception 03
 * and the request (with its cycle trigger) changes nothing. */
static void test_temperatures(void **state)
{
    (void)state;
    size_t fsize;
    const uint8_t *full = full_blob(&fsize);
    abbe_comp_t local;
    abbe_model_t slot;
    abbe_mb_regs_config_t cfg;
    abbe_mb_regs_default_config(&cfg);
    cfg.comp.fade_cycles = 1;
    for (int j = 0; j < 3; j++) {
        cfg.comp.warn_nm[j] = 100000000;
        cfg.comp.limit_nm[j] = 200000000;
        cfg.comp.rate_nm_per_cycle[j] = 100000000;
    }
    assert_int_equal(abbe_mb_regs_init(&R, &cfg, full, fsize), ABBE_OK);
    assert_int_equal(abbe_comp_init(&local, &cfg.comp, NULL), ABBE_OK);
    assert_int_equal(abbe_comp_load_model(&local, &slot, full, fsize), ABBE_OK);
    assert_int_equal(wr1(A, ABBE_MB_REG_CT_ENABLE, 1), 0);
    assert_int_equal(abbe_comp_enable(&local), ABBE_OK);
    for (int j = 0; j < 3; j++) {
        assert_int_equal(rd1((uint16_t)(ABBE_MB_REG_IN_TEMP_X + j)), 2000); /* 20 degC until written */
    }
    int32_t cur[3] = {20000, 20000, 20000};
    int32_t err20 = 0, err_hot = 0;
    const int16_t temps[][3] = {
        {2000, 2000, 2000}, {3500, 1800, -32768}, {-32768, -32768, 2600}, {-5000, 15000, 2150}, {4000, 4000, 4000},
    };
    for (int k = 0; k < 5; k++) {
        int32_t p[3] = {500000000, -700000000, -300000000};
        uint16_t in[ABBE_MB_IN_COUNT] = {0};
        abbe_comp_input_q_t li;
        abbe_comp_output_t lo;
        memset(&li, 0, sizeof li);
        for (int j = 0; j < 3; j++) {
            mbt_put32(&in[2 * j], (uint32_t)p[j], 0);
            in[9 + j] = (uint16_t)temps[k][j];
            if (temps[k][j] != ABBE_MB_TEMP_NO_READING) {
                cur[j] = 10 * temps[k][j];
            }
            li.pos_nm[j] = p[j];
            li.temp_mdegc[j] = cur[j];
        }
        li.fresh = 1;
        in[13] = (uint16_t)k;
        assert_int_equal(wr(A, ABBE_MB_REG_IN_BASE, ABBE_MB_IN_COUNT, in), 0);
        assert_int_equal(abbe_comp_step_q(&local, &li, &lo), ABBE_OK);
        for (int j = 0; j < 3; j++) {
            assert_int_equal((int32_t)rd32((uint16_t)(ABBE_MB_REG_OUT_CORR_X + 2 * j)), lo.corr_nm[j]);
            assert_int_equal((int16_t)rd1((uint16_t)(ABBE_MB_REG_IN_TEMP_X + j)), cur[j] / 10);
        }
        if (k == 0) {
            err20 = (int32_t)rd32(ABBE_MB_REG_OUT_ERR_X);
        }
        if (k == 4) {
            err_hot = (int32_t)rd32(ABBE_MB_REG_OUT_ERR_X);
        }
    }
    assert_true(abs(err_hot - err20) > 10000); /* 20 K on X moves its error by > 10 um */

    /* out of range: exception 03, no cycle, no temperature taken */
    uint32_t cycles = rd32(ABBE_MB_REG_ST_CYCLES);
    const int16_t bad[] = {-5001, 15001, 0x7FFF, -32767};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        uint16_t in[5] = {2100, (uint16_t)bad[i], 2100, 0, 99}; /* IN_TEMP_X .. IN_CYCLE */
        assert_int_equal(wr(A, ABBE_MB_REG_IN_TEMP_X, 5, in), ABBE_MB_EX_ILLEGAL_VALUE);
        assert_int_equal(rd32(ABBE_MB_REG_ST_CYCLES), cycles);
        assert_int_equal(rd1(ABBE_MB_REG_IN_TEMP_X), 4000);
        assert_int_equal(rd1(ABBE_MB_REG_IN_TEMP_Y), 4000);
        assert_true(rd1(ABBE_MB_REG_OUT_CYCLE) != 99);
    }
}

/* The event hook sees every session begun, ended (with the result that
 * UP_RESULT shows and the session it belonged to) or refused as busy, and
 * every table taken into use, in order. */
#define MAX_EVENTS 32
static abbe_mb_event_t events[MAX_EVENTS];
static int n_events;

static void record_event(void *ctx, const abbe_mb_event_t *ev)
{
    assert_ptr_equal(ctx, &n_events);
    assert_true(n_events < MAX_EVENTS);
    events[n_events++] = *ev;
}

static void expect_event(int i, abbe_mb_event_kind_t kind, uint32_t conn, uint16_t session, int16_t result)
{
    assert_true(i < n_events);
    assert_int_equal(events[i].kind, kind);
    assert_int_equal(events[i].conn, conn);
    assert_int_equal(events[i].session, session);
    assert_int_equal(events[i].result, result);
}

static void test_event_hook(void **state)
{
    (void)state;
    size_t fsize;
    const uint8_t *full = full_blob(&fsize);
    n_events = 0;
    abbe_mb_regs_set_event_hook(&R, record_event, &n_events);
    assert_int_equal(upload(A, paper, paper_size), 0);                    /* session 1: OK */
    assert_int_equal(n_events, 2);
    expect_event(0, ABBE_MB_EV_UPLOAD_BEGIN, A, 1, 0);
    expect_event(1, ABBE_MB_EV_UPLOAD_END, A, 1, ABBE_MB_UP_OK);
    assert_int_equal(events[1].crc, table_crc(paper, paper_size));
    assert_int_equal(events[1].size, paper_size);
    uint16_t c = 77;
    assert_int_equal(wr(A, ABBE_MB_REG_IN_CYCLE, 1, &c), 0);               /* takes effect */
    assert_int_equal(events[2].kind, ABBE_MB_EV_MODEL_SWAP);
    assert_int_equal(events[2].cycle, 77);
    assert_int_equal(events[2].crc, table_crc(paper, paper_size));
    cycle();
    assert_int_equal(n_events, 3);                                          /* nothing more to swap */

    assert_int_equal(begin(A), 0);                                          /* session 2 */
    assert_int_equal(begin(B), ABBE_MB_EX_BUSY);                            /* B refused: 2 is A's */
    expect_event(4, ABBE_MB_EV_UPLOAD_BUSY, B, 2, 0);
    assert_int_equal(events[4].owner, A);
    assert_int_equal(begin(A), 0);                                          /* 2 aborted, 3 begun */
    expect_event(5, ABBE_MB_EV_UPLOAD_END, A, 2, ABBE_MB_UP_ABORTED);
    expect_event(6, ABBE_MB_EV_UPLOAD_BEGIN, A, 3, 0);
    abbe_mb_regs_disconnect(&R, A);
    expect_event(7, ABBE_MB_EV_UPLOAD_END, A, 3, ABBE_MB_UP_DISCONNECTED);
    assert_int_equal(begin(B), 0);                                          /* 4: B times out */
    abbe_mb_regs_tick(&R, 5000 + 1000);
    expect_event(9, ABBE_MB_EV_UPLOAD_END, B, 4, ABBE_MB_UP_TIMEOUT);
    static uint8_t bad[ABBE_MB_STAGING_MAX];
    memcpy(bad, full, fsize);
    bad[0] = 'X';
    assert_int_equal(upload(A, bad, fsize), ABBE_MB_EX_ILLEGAL_VALUE);     /* 5: the table's status */
    expect_event(11, ABBE_MB_EV_UPLOAD_END, A, 5, ABBE_E_MAGIC);
    assert_int_equal(n_events, 12);
    /* every END carried what UP_RESULT then showed */
    assert_int_equal((int16_t)rd1(ABBE_MB_REG_UP_RESULT), ABBE_E_MAGIC);
    abbe_mb_regs_set_event_hook(&R, NULL, NULL);
    assert_int_equal(begin(A), 0);
    assert_int_equal(n_events, 12);
}

static void test_limits_change_keeps_models_and_counters(void **state)
{
    (void)state;
    size_t fsize;
    const uint8_t *full = full_blob(&fsize);
    running_paper();
    assert_int_equal(upload(A, full, fsize), 0); /* queued, not yet running */
    uint32_t cycles = rd32(ABBE_MB_REG_ST_CYCLES);
    uint16_t stale = 4;
    assert_int_equal(wr(A, ABBE_MB_REG_CT_STALE_CYCLES, 1, &stale), 0);
    assert_int_equal(rd32(ABBE_MB_REG_ID_MODEL_CRC), table_crc(paper, paper_size));
    assert_int_equal(rd32(ABBE_MB_REG_ID_PENDING_CRC), table_crc(full, fsize));
    assert_int_equal(rd32(ABBE_MB_REG_ST_CYCLES), cycles);
    cycle();
    assert_int_equal(rd32(ABBE_MB_REG_ID_MODEL_CRC), table_crc(full, fsize));
    assert_int_equal(rd32(ABBE_MB_REG_ST_CYCLES), cycles + 1);
}

static void test_fault_reset(void **state)
{
    (void)state;
    size_t fsize;
    const uint8_t *full = full_blob(&fsize);
    abbe_mb_regs_config_t cfg;
    abbe_mb_regs_default_config(&cfg);
    for (int j = 0; j < 3; j++) {
        cfg.comp.warn_nm[j] = 1000;
        cfg.comp.limit_nm[j] = 2000; /* the full table's errors are far larger */
    }
    assert_int_equal(abbe_mb_regs_init(&R, &cfg, full, fsize), ABBE_OK);
    assert_int_equal(wr1(A, ABBE_MB_REG_CT_ENABLE, 1), 0);
    uint16_t in[ABBE_MB_IN_COUNT] = {0};
    mbt_put32(&in[0], 1900000000u, 0);
    assert_int_equal(wr(A, ABBE_MB_REG_IN_BASE, ABBE_MB_IN_COUNT, in), 0);
    assert_int_equal(rd1(ABBE_MB_REG_OUT_STATE), ABBE_COMP_FAULT);
    assert_true(rd1(ABBE_MB_REG_OUT_FLAGS) & ABBE_FLAG_LIMIT);
    assert_int_equal(rd32(ABBE_MB_REG_ST_LIMIT_TRIPS), 1);
    assert_int_equal(rd32(ABBE_MB_REG_OUT_CORR_X), 0); /* fault: output stays at zero */
    assert_int_equal(wr1(A, ABBE_MB_REG_CT_RESET, 1), 0);
    assert_int_equal(rd1(ABBE_MB_REG_CT_ENABLE), 0);
    assert_int_equal(rd1(ABBE_MB_REG_CT_RESET), 0);
    /* the latch is cleared: a position with a small error runs OFF, and
     * the large one trips (and counts) again */
    mbt_put32(&in[0], 1000000000u, 0);
    mbt_put32(&in[2], (uint32_t)-1000000000, 0);
    mbt_put32(&in[4], (uint32_t)-500000000, 0); /* the reference point, at T_ref: error 0 */
    in[9] = 2000;
    in[10] = 2000;
    in[11] = 2150;
    assert_int_equal(wr(A, ABBE_MB_REG_IN_BASE, ABBE_MB_IN_COUNT, in), 0);
    assert_int_equal(rd1(ABBE_MB_REG_OUT_STATE), ABBE_COMP_OFF);
    mbt_put32(&in[0], 1900000000u, 0);
    assert_int_equal(wr(A, ABBE_MB_REG_IN_BASE, ABBE_MB_IN_COUNT, in), 0);
    assert_int_equal(rd1(ABBE_MB_REG_OUT_STATE), ABBE_COMP_FAULT);
    assert_int_equal(rd32(ABBE_MB_REG_ST_LIMIT_TRIPS), 2);

    /* from FAULT (output zero), one request resets, sets wider limits and
     * enables (docs: reset, then the limits, then enable); without the reset
     * the limits are refused while faulted */
    uint16_t ct[ABBE_MB_CT_COUNT] = {0};
    ct[0] = 1; /* enable */
    ct[1] = 1; /* reset */
    ct[4] = 1;
    ct[5] = 10;
    for (int j = 0; j < 3; j++) {
        mbt_put32(&ct[6 + 2 * j], 100000000u, 0);
        mbt_put32(&ct[12 + 2 * j], 200000000u, 0);
        mbt_put32(&ct[18 + 2 * j], 100000000u, 0);
        ct[24 + j] = 1;
    }
    assert_int_equal(wr(A, ABBE_MB_REG_CT_FADE_CYCLES, ABBE_MB_CT_COUNT - 4, &ct[4]), ABBE_MB_EX_ILLEGAL_FUNCTION);
    assert_int_equal(wr(A, ABBE_MB_REG_CT_BASE, ABBE_MB_CT_COUNT, ct), 0);
    assert_int_equal(rd1(ABBE_MB_REG_CT_ENABLE), 1);
    assert_int_equal((int32_t)rd32(ABBE_MB_REG_CT_LIMIT_X), 200000000);
    assert_int_equal(wr(A, ABBE_MB_REG_IN_BASE, ABBE_MB_IN_COUNT, in), 0);
    assert_int_equal(rd1(ABBE_MB_REG_OUT_STATE), ABBE_COMP_ON);
    assert_int_equal(rd32(ABBE_MB_REG_ST_LIMIT_TRIPS), 2);
}

static void test_init_args(void **state)
{
    (void)state;
    abbe_mb_regs_config_t cfg;
    abbe_mb_regs_default_config(&cfg);
    assert_int_equal(abbe_mb_regs_init(NULL, &cfg, NULL, 0), ABBE_E_ARG);
    assert_int_equal(abbe_mb_regs_init(&R, NULL, NULL, 0), ABBE_E_ARG);
    cfg.word_order = 2;
    assert_int_equal(abbe_mb_regs_init(&R, &cfg, NULL, 0), ABBE_E_ARG);
    abbe_mb_regs_default_config(&cfg);
    cfg.comp.fade_cycles = 0;
    assert_int_equal(abbe_mb_regs_init(&R, &cfg, NULL, 0), ABBE_E_ARG);
    abbe_mb_regs_default_config(&cfg);
    assert_int_equal(abbe_mb_regs_init(&R, &cfg, paper, ABBE_MB_STAGING_MAX + 1u), ABBE_E_ARG);
    static uint8_t bad[2048];
    memcpy(bad, paper, paper_size);
    bad[0] = 0;
    assert_int_equal(abbe_mb_regs_init(&R, &cfg, bad, paper_size), ABBE_E_MAGIC);
    assert_int_equal(rd32(ABBE_MB_REG_ID_MODEL_CRC), 0); /* usable, without a model */
    assert_int_equal(abbe_mb_regs_init(&R, &cfg, paper, paper_size), ABBE_OK);
    assert_int_equal(rd32(ABBE_MB_REG_ID_MODEL_CRC), table_crc(paper, paper_size));
}

int main(void)
{
    long n = mbt_read_file(ABBE_EXAMPLE_MODEL, paper, sizeof paper);
    if (n <= 0) {
        return 1;
    }
    paper_size = (size_t)n;
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup(test_identity, setup),
        cmocka_unit_test_setup(test_read_exceptions, setup),
        cmocka_unit_test_setup(test_write_exceptions, setup),
        cmocka_unit_test_setup(test_limits_only_when_off, setup),
        cmocka_unit_test_setup(test_upload_ok_and_swap_at_cycle, setup),
        cmocka_unit_test_setup(test_upload_refused, setup),
        cmocka_unit_test_setup(test_upload_second_client, setup),
        cmocka_unit_test_setup(test_upload_disconnect_and_timeout, setup),
        cmocka_unit_test_setup(test_cycle_trigger_and_fresh, setup),
        cmocka_unit_test_setup(test_dir_from_position, setup),
        cmocka_unit_test_setup(test_temperatures, setup),
        cmocka_unit_test_setup(test_event_hook, setup),
        cmocka_unit_test_setup(test_limits_change_keeps_models_and_counters, setup),
        cmocka_unit_test_setup(test_fault_reset, setup),
        cmocka_unit_test_setup(test_init_args, setup),
    };
    return cmocka_run_group_tests_name("modbus_regs", tests, NULL, NULL);
}
