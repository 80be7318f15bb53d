/* libFuzzer harness: the Modbus register map engine (abbe_mb_regs_*,
 * docs/modbus-registers.md) driven by a session of requests from up to three
 * connections: reads and writes anywhere with any count and values, whole
 * input-block cycles, control writes, uploads of golden tables (mutated or
 * not, chunked, committed right or wrong), BEGIN/ABORT, commits, staging
 * chunks, clock ticks and disconnects, in the order the bytes say.
 *
 * Checked beyond "no sanitizer report", after every request:
 *   - the answer is 0 or a documented exception (01, 02, 03, 06);
 *   - a request that gets an exception changes nothing but the counters
 *     (the whole state is compared), except a refused commit, which closes
 *     its owner's session;
 *   - a successful write reads back as written (register map blocks; not
 *     the command registers, a kept temperature or a word-order change);
 *   - no byte of the running or the queued table is ever written (their
 *     CRC-32 still holds), and ID_MODEL_CRC / ID_PENDING_CRC name them;
 *   - identity, self-test in the word order, UP_STATE = ST_UPLOAD_STATE,
 *     UP_RESULT in its documented set; a correction beyond its axis' error
 *     limit only while the fault is latched and fading out (a limit lowered
 *     below the running correction trips the fault; the output then fades,
 *     never jumps and never grows);
 *   - the event hook reports what the registers then show.
 */
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "abbe/modbus_port.h"
#include "fuzz_input.h"
#include "golden_data.h"

#define CHECK(cond)                                                                               \
    do {                                                                                          \
        if (!(cond)) {                                                                            \
            fprintf(stderr, "fuzz_modbus_regs: check failed: %s (line %d)\n", #cond, __LINE__);    \
            abort();                                                                              \
        }                                                                                         \
    } while (0)

#define MAX_STEPS 400u
#define STAGING_REGS (ABBE_MB_STAGING_MAX / 2)

static abbe_mb_regs_t R;
static abbe_mb_regs_t snap;
static uint32_t blob_words[ABBE_MB_STAGING_MAX / 4];
#define g_blob ((uint8_t *)blob_words)
static unsigned n_events;
static int snap_banks;  /* the snapshot holds the table banks too */
static int32_t last_corr[ABBE_AXES]; /* OUT_CORR at the previous check */
static int banks_touched; /* check the tables' CRCs at the next check_invariants: after
                             every upload step, every 32 steps and at the end */

/* The snapshot of the state before a request: everything but the table
 * banks, and the staging bank for requests that can reach it (upload and
 * staging registers; no other code path writes a bank). The running and the
 * queued table are checked by their CRC-32 instead (check_table). */
#define BANKS_OFF offsetof(abbe_mb_regs_t, bank)
#define BANKS_END (BANKS_OFF + sizeof R.bank)

static int touches_banks(uint16_t addr, uint16_t count)
{
    uint32_t end = (uint32_t)addr + count;
    return (addr < ABBE_MB_REG_UP_BASE + ABBE_MB_UP_COUNT && end > ABBE_MB_REG_UP_BASE) ||
           end > ABBE_MB_REG_STAGING;
}

static void take_snapshot(int with_banks)
{
    memcpy(&snap, &R, BANKS_OFF);
    memcpy((uint8_t *)&snap + BANKS_END, (const uint8_t *)&R + BANKS_END, sizeof R - BANKS_END);
    snap_banks = with_banks && R.staging >= 0;
    if (snap_banks) {
        memcpy(snap.bank[R.staging], R.bank[R.staging], sizeof R.bank[0]);
    }
}

static int same_as_snapshot(void)
{
    return memcmp(&snap, &R, BANKS_OFF) == 0 &&
           memcmp((const uint8_t *)&snap + BANKS_END, (const uint8_t *)&R + BANKS_END, sizeof R - BANKS_END) == 0 &&
           (!snap_banks || memcmp(snap.bank[snap.staging], R.bank[snap.staging], sizeof R.bank[0]) == 0);
}

/* ---- helpers -------------------------------------------------------------------- */

static uint32_t get32(const uint16_t *v, uint8_t order)
{
    return order == ABBE_MB_WORD_ORDER_LOW_FIRST ? ((uint32_t)v[1] << 16) | v[0] : ((uint32_t)v[0] << 16) | v[1];
}

static void put32(uint16_t *v, uint32_t x, uint8_t order)
{
    uint16_t hi = (uint16_t)(x >> 16), lo = (uint16_t)(x & 0xFFFFu);
    v[0] = order == ABBE_MB_WORD_ORDER_LOW_FIRST ? lo : hi;
    v[1] = order == ABBE_MB_WORD_ORDER_LOW_FIRST ? hi : lo;
}

static int write_regs(uint32_t conn, uint16_t addr, uint16_t count, const uint16_t *v)
{
    static uint8_t be[2 * 256];
    for (uint16_t i = 0; i < count && i < 256u; i++) {
        be[2 * i] = (uint8_t)(v[i] >> 8);
        be[2 * i + 1] = (uint8_t)(v[i] & 0xFFu);
    }
    return abbe_mb_regs_write(&R, conn, addr, count, be);
}

static void read_ok(uint16_t addr, uint16_t count, uint16_t *dst)
{
    CHECK(abbe_mb_regs_read(&R, 1u, addr, count, dst) == 0);
}

static uint32_t read32(uint16_t addr)
{
    uint16_t v[2];
    read_ok(addr, 2, v);
    return get32(v, R.word_order);
}

static int in_block(uint16_t addr, uint16_t base, uint16_t count)
{
    return addr >= base && addr < base + count;
}

/* ---- invariants ------------------------------------------------------------------- */

static void check_table(int8_t bank)
{
    if (bank < 0) {
        return;
    }
    const abbe_model_t *m = &R.slot[bank];
    uint32_t size = abbe_model_size(m);
    CHECK(size >= 260u && size <= ABBE_MB_STAGING_MAX);
    CHECK(abbe_crc32(0u, R.bank[bank], size - 4u) == abbe_model_crc(m));
}

static void check_invariants(void)
{
    CHECK(R.running >= -1 && R.running < ABBE_MB_BANKS && R.pending >= -1 && R.pending < ABBE_MB_BANKS);
    CHECK(R.running < 0 || R.running != R.pending);
    if (banks_touched) {
        check_table(R.running);
        check_table(R.pending);
        banks_touched = 0;
    }
    uint16_t id[ABBE_MB_ID_COUNT];
    read_ok(ABBE_MB_REG_ID_BASE, ABBE_MB_ID_COUNT, id);
    CHECK(id[0] == ABBE_MB_MAGIC_HI && id[1] == ABBE_MB_MAGIC_LO && id[2] == ABBE_MB_REGMAP_VERSION);
    CHECK(get32(&id[8], R.word_order) == ABBE_MB_SELFTEST_VALUE);
    CHECK(get32(&id[10], R.word_order) == (R.running >= 0 ? abbe_model_crc(&R.slot[R.running]) : 0u));
    CHECK(get32(&id[14], R.word_order) == (R.pending >= 0 ? abbe_model_crc(&R.slot[R.pending]) : 0u));
    CHECK(get32(&id[16], R.word_order) == ABBE_MB_STAGING_MAX);
    uint16_t st[ABBE_MB_ST_COUNT], up[ABBE_MB_UP_COUNT], ct[ABBE_MB_CT_COUNT], out[ABBE_MB_OUT_COUNT];
    read_ok(ABBE_MB_REG_ST_BASE, ABBE_MB_ST_COUNT, st);
    read_ok(ABBE_MB_REG_UP_BASE, ABBE_MB_UP_COUNT, up);
    read_ok(ABBE_MB_REG_CT_BASE, ABBE_MB_CT_COUNT, ct);
    read_ok(ABBE_MB_REG_OUT_BASE, ABBE_MB_OUT_COUNT, out);
    CHECK(st[0] <= 2u && out[13] == st[0] && out[12] == st[1]);
    CHECK(st[3] == up[1] && up[1] <= 1u && up[0] == 0u && ct[1] == 0u);
    int16_t result = (int16_t)up[3];
    CHECK(result == ABBE_MB_UP_OK || result == ABBE_MB_UP_NONE || (result < 0 && result >= ABBE_STATUS_MIN) ||
          (result <= ABBE_MB_UP_INCOMPLETE && result >= ABBE_MB_UP_TIMEOUT));
    CHECK((st[1] & 0xE00Cu) == 0u); /* reserved flag bits */
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        int32_t corr = (int32_t)get32(&out[2 * j], R.word_order);
        int32_t limit = (int32_t)get32(&ct[12 + 2 * j], R.word_order);
        int64_t mag = corr < 0 ? -(int64_t)corr : corr;
        int64_t last = last_corr[j] < 0 ? -(int64_t)last_corr[j] : last_corr[j];
        CHECK(mag <= limit || (st[0] == ABBE_COMP_FAULT && mag <= last));
        last_corr[j] = corr;
        int16_t t = (int16_t)R.temp_cdegc[j];
        CHECK(t >= ABBE_MB_TEMP_MIN_CDEGC && t <= ABBE_MB_TEMP_MAX_CDEGC);
    }
}

/* A request that got an exception left everything as it was (but the
 * counters); a refused commit only closed its session. */
static void check_unchanged(int ex, uint32_t conn, uint16_t addr, uint16_t count)
{
    if (ex == 0) {
        return;
    }
    CHECK(ex == ABBE_MB_EX_ILLEGAL_FUNCTION || ex == ABBE_MB_EX_ILLEGAL_ADDRESS ||
          ex == ABBE_MB_EX_ILLEGAL_VALUE || ex == ABBE_MB_EX_BUSY);
    if (addr == ABBE_MB_REG_UP_COMMIT && count == 4u && snap.owner == conn && ex == ABBE_MB_EX_ILLEGAL_VALUE) {
        CHECK(R.owner == 0u && R.result != ABBE_MB_UP_NONE && R.result != ABBE_MB_UP_OK);
        CHECK(R.uploads_rejected == snap.uploads_rejected + 1u);
        return;
    }
    snap.uploads_rejected = R.uploads_rejected; /* a BEGIN refused as busy counts */
    snap.last_activity_ms = R.last_activity_ms; /* any upload request of the owner is activity */
    CHECK(same_as_snapshot());
}

/* A successful write reads back as written. */
static void check_read_back(uint16_t addr, uint16_t count, const uint16_t *v)
{
    if (R.word_order != snap.word_order) {
        return; /* its 32-bit values now read in the new order */
    }
    int in = in_block(addr, ABBE_MB_REG_IN_BASE, ABBE_MB_IN_COUNT);
    int ct = in_block(addr, ABBE_MB_REG_CT_BASE, ABBE_MB_CT_COUNT);
    if (!in && !ct) {
        return;
    }
    uint16_t got[128];
    read_ok(addr, count, got);
    for (uint16_t i = 0; i < count; i++) {
        uint16_t a = (uint16_t)(addr + i);
        if (a == ABBE_MB_REG_CT_RESET) {
            CHECK(got[i] == 0u);
        } else if (a >= ABBE_MB_REG_IN_TEMP_X && a <= ABBE_MB_REG_IN_TEMP_Z && v[i] == 0x8000u) {
            CHECK(got[i] == snap.temp_cdegc[a - ABBE_MB_REG_IN_TEMP_X] ||
                  (uint16_t)snap.temp_cdegc[a - ABBE_MB_REG_IN_TEMP_X] == got[i]);
        } else {
            CHECK(got[i] == v[i]);
        }
    }
}

static void on_event(void *ctx, const abbe_mb_event_t *ev)
{
    CHECK(ctx == &n_events);
    n_events++;
    switch (ev->kind) {
    case ABBE_MB_EV_UPLOAD_BEGIN:
        CHECK(R.owner == ev->conn && ev->conn != 0u && R.session == ev->session && R.result == ABBE_MB_UP_NONE);
        break;
    case ABBE_MB_EV_UPLOAD_END:
        CHECK(R.owner == 0u && ev->conn != 0u && R.session == ev->session && R.result == ev->result);
        CHECK(ev->result != ABBE_MB_UP_OK || (R.pending >= 0 && ev->crc == abbe_model_crc(&R.slot[R.pending])));
        break;
    case ABBE_MB_EV_UPLOAD_BUSY:
        CHECK(R.owner != 0u && R.owner == ev->owner && ev->conn != ev->owner && R.session == ev->session);
        break;
    case ABBE_MB_EV_MODEL_SWAP:
        CHECK(R.running >= 0 && R.pending < 0 && ev->crc == abbe_model_crc(&R.slot[R.running]));
        CHECK(ev->size == abbe_model_size(&R.slot[R.running]) && ev->cycle == R.cycle_in);
        break;
    default: CHECK(0);
    }
}

/* ---- requests ------------------------------------------------------------------------- */

static uint16_t pick_addr(fz_reader_t *in)
{
    static const uint16_t bases[] = {ABBE_MB_REG_ID_BASE, ABBE_MB_REG_ST_BASE, ABBE_MB_REG_UP_BASE,
                                     ABBE_MB_REG_IN_BASE, ABBE_MB_REG_OUT_BASE, ABBE_MB_REG_CT_BASE,
                                     ABBE_MB_REG_STAGING, ABBE_MB_REG_STAGING + STAGING_REGS};
    uint8_t how = fz_u8(in);
    if (how & 0x80u) {
        return fz_u16(in);
    }
    int off = (int)(fz_u8(in) % 36u) - 2;
    return (uint16_t)((int)bases[how % 8u] + off);
}

static uint16_t pick_count(fz_reader_t *in)
{
    uint8_t c = fz_u8(in);
    return (c & 0x80u) ? (uint16_t)fz_u8(in) : (uint16_t)(c % 28u + (c & 0x40u ? 0u : 1u));
}

static uint32_t pick_conn(fz_reader_t *in)
{
    return 1u + fz_u8(in) % 3u;
}

static int do_write(uint32_t conn, uint16_t addr, uint16_t count, const uint16_t *v)
{
    take_snapshot(touches_banks(addr, count));
    int ex = write_regs(conn, addr, count, v);
    check_unchanged(ex, conn, addr, count);
    if (ex == 0) {
        check_read_back(addr, count, v);
    }
    check_invariants();
    return ex;
}

static void step_read(fz_reader_t *in)
{
    uint32_t conn = pick_conn(in);
    uint16_t addr = pick_addr(in), count = pick_count(in);
    static uint16_t dst[256];
    take_snapshot(touches_banks(addr, count));
    int ex = abbe_mb_regs_read(&R, conn, addr, count, dst);
    CHECK(ex == 0 || ex == ABBE_MB_EX_ILLEGAL_FUNCTION || ex == ABBE_MB_EX_ILLEGAL_ADDRESS ||
          ex == ABBE_MB_EX_ILLEGAL_VALUE || ex == ABBE_MB_EX_BUSY);
    CHECK(abbe_mb_regs_check_read(&R, conn, addr, count) == ex);
    snap.last_activity_ms = R.last_activity_ms; /* the owner's staging read is activity */
    CHECK(same_as_snapshot());                   /* a read changes nothing */
    if (ex == 0 && addr >= ABBE_MB_REG_STAGING) {
        CHECK(R.owner == conn);
        const uint8_t *p = &R.bank[R.staging][2u * (uint32_t)(addr - ABBE_MB_REG_STAGING)];
        for (uint16_t i = 0; i < count; i++) {
            CHECK(dst[i] == (uint16_t)((p[2 * i] << 8) | p[2 * i + 1]));
        }
    }
}

static void step_write_raw(fz_reader_t *in)
{
    uint32_t conn = pick_conn(in);
    uint16_t addr = pick_addr(in), count = pick_count(in);
    static uint16_t v[256];
    for (uint16_t i = 0; i < count && i < 256u; i++) {
        v[i] = fz_u16(in);
    }
    banks_touched = touches_banks(addr, count);
    (void)do_write(conn, addr, count, v);
}

/* The controller's cycle: the whole input block, mostly valid values. */
static void step_cycle(fz_reader_t *in)
{
    uint16_t v[ABBE_MB_IN_COUNT];
    uint8_t how = fz_u8(in);
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        int32_t pos = (int32_t)fz_u32(in);
        if (!(how & 1u)) {
            pos = (int32_t)(pos % 1000000000); /* within +/-1 m */
        }
        put32(&v[2 * j], (uint32_t)pos, R.word_order);
        v[6 + j] = (uint16_t)((int)(fz_u8(in) % 3u) - 1 + ((how & 2u) ? 3 : 0)); /* -1..1, or out of range */
        uint16_t t = fz_u16(in);
        v[9 + j] = (how & 4u) ? t : (t & 1u) ? 0x8000u : (uint16_t)(t % 20001u - 5000u);
    }
    v[12] = (uint16_t)(fz_u8(in) % ((how & 8u) ? 16u : 8u));
    v[13] = fz_u16(in);
    (void)do_write(pick_conn(in), ABBE_MB_REG_IN_BASE, ABBE_MB_IN_COUNT, v);
}

/* Control registers: one setting, or the limit set, or all of them. */
static void step_control(fz_reader_t *in)
{
    uint16_t v[ABBE_MB_CT_COUNT];
    uint8_t how = fz_u8(in);
    v[0] = fz_u8(in) % 2u;
    v[1] = fz_u8(in) % 4u == 0u;
    v[2] = (how & 0x10u) ? R.word_order ^ 1u : R.word_order;
    v[3] = fz_u8(in) % 2u;
    v[4] = (uint16_t)(fz_u8(in) % 20u);
    v[5] = (uint16_t)(fz_u8(in) % 20u);
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        int32_t warn = 1000 * (int32_t)fz_u8(in), limit = warn + 1000 * (int32_t)fz_u8(in),
                rate = (int32_t)fz_u16(in);
        put32(&v[6 + 2 * j], (uint32_t)warn, R.word_order);
        put32(&v[12 + 2 * j], (uint32_t)limit, R.word_order);
        put32(&v[18 + 2 * j], (uint32_t)rate, R.word_order);
        v[24 + j] = (fz_u8(in) & 1u) ? 1u : 0xFFFFu;
    }
    uint16_t from, n;
    switch (how % 4u) {
    case 0: from = 0; n = ABBE_MB_CT_COUNT; break;              /* everything: reset, limits, enable */
    case 1: from = 4; n = ABBE_MB_CT_COUNT - 4u; break;          /* the limits */
    case 2: from = (uint16_t)(fz_u8(in) % 4u); n = 1; break;     /* one setting */
    default: from = 0; n = 4; break;
    }
    (void)do_write(pick_conn(in), (uint16_t)(ABBE_MB_REG_CT_BASE + from), n, &v[from]);
}

static int commit(uint32_t conn, uint32_t len, uint32_t crc)
{
    uint16_t v[4];
    put32(&v[0], len, R.word_order);
    put32(&v[2], crc, R.word_order);
    return do_write(conn, ABBE_MB_REG_UP_COMMIT, 4, v);
}

static int chunk(uint32_t conn, uint32_t off, uint32_t len)
{
    uint16_t v[123];
    uint16_t n = (uint16_t)((len + 1u) / 2u);
    for (uint16_t i = 0; i < n; i++) {
        uint32_t b = off + 2u * i;
        v[i] = (uint16_t)((g_blob[b] << 8) | (b + 1u < ABBE_MB_STAGING_MAX ? g_blob[b + 1u] : 0u));
    }
    return do_write(conn, (uint16_t)(ABBE_MB_REG_STAGING + off / 2u), n, v);
}

/* An upload: BEGIN, chunks, COMMIT, of a golden table (maybe damaged). */
static void step_upload(fz_reader_t *in)
{
    uint32_t conn = pick_conn(in);
    const abbe_golden_table_t *t = &abbe_golden_tables[fz_u8(in) % abbe_golden_table_count];
    uint8_t how = fz_u8(in);
    uint32_t size = t->blob_size;
    memset(g_blob, 0, ABBE_MB_STAGING_MAX);
    memcpy(g_blob, t->blob, size);
    if (how & 1u) { /* a byte changed (CRC fixed up when how & 2: the table checks see it) */
        g_blob[fz_u16(in) % size] ^= (uint8_t)(1u | fz_u8(in));
        if (how & 2u) {
            uint32_t total = (uint32_t)g_blob[8] | (uint32_t)g_blob[9] << 8 | (uint32_t)g_blob[10] << 16 |
                             (uint32_t)g_blob[11] << 24;
            if (total >= 8u && total <= size) {
                uint32_t c = abbe_crc32(0u, g_blob, total - 4u);
                for (unsigned k = 0; k < 4u; k++) {
                    g_blob[total - 4u + k] = (uint8_t)(c >> (8u * k));
                }
            }
        }
    }
    uint16_t one = ABBE_MB_UP_CMD_BEGIN;
    if (do_write(conn, ABBE_MB_REG_UP_CMD, 1, &one) != 0) {
        return;
    }
    uint32_t step = 2u * (16u + fz_u8(in) % 108u); /* 16..123 registers a chunk */
    uint32_t end = (how & 4u) ? size - fz_u8(in) % 64u : size; /* maybe short */
    for (uint32_t off = 0; off < end; off += step) {
        if (chunk(conn, off, end - off < step ? end - off : step) != 0) {
            return;
        }
        if ((how & 8u) && off == step) {
            (void)chunk(conn, 0, step); /* a retried chunk */
        }
    }
    uint32_t len = (how & 16u) ? (uint32_t)fz_u16(in) : size;
    uint32_t crc = (how & 32u) ? fz_u32(in) : abbe_crc32(0u, g_blob, len <= ABBE_MB_STAGING_MAX ? len : 0u);
    uint32_t events = n_events;
    banks_touched = 1;
    int ex = commit(conn, len, crc);
    CHECK(n_events == events + 1u); /* the session ended, reported once */
    if (ex == 0) {
        CHECK(R.result == ABBE_MB_UP_OK && R.pending >= 0);
        CHECK(read32(ABBE_MB_REG_ID_PENDING_CRC) == read32(ABBE_MB_REG_UP_MODEL_CRC));
        abbe_model_t m;
        CHECK(abbe_model_load(&m, g_blob, len) == ABBE_OK && abbe_model_crc(&m) == read32(ABBE_MB_REG_UP_MODEL_CRC));
    } else {
        CHECK(ex == ABBE_MB_EX_ILLEGAL_VALUE && R.result != ABBE_MB_UP_OK);
    }
}

static void step_misc(fz_reader_t *in)
{
    uint8_t what = fz_u8(in);
    uint32_t conn = pick_conn(in);
    banks_touched = what % 7u <= 2u; /* BEGIN/ABORT, commit, chunk */
    switch (what % 7u) {
    case 0: { /* BEGIN or ABORT or another value */
        uint16_t v = (uint16_t)(fz_u8(in) % 4u);
        (void)do_write(conn, ABBE_MB_REG_UP_CMD, 1, &v);
        break;
    }
    case 1: (void)commit(conn, fz_u16(in), fz_u32(in)); break;
    case 2: { /* a chunk somewhere in the staging area */
        uint32_t off = 2u * (fz_u16(in) % STAGING_REGS);
        uint32_t len = 2u * (1u + fz_u8(in) % 123u);
        fz_bytes(in, g_blob + (off < ABBE_MB_STAGING_MAX - 246u ? off : 0u), 16);
        (void)chunk(conn, off < ABBE_MB_STAGING_MAX - len ? off : ABBE_MB_STAGING_MAX - len, len);
        break;
    }
    case 3: { /* time passes */
        uint32_t dt = (what & 0x80u) ? fz_u32(in) : fz_u16(in);
        abbe_mb_regs_tick(&R, R.now_ms + dt);
        check_invariants();
        break;
    }
    case 4:
        abbe_mb_regs_disconnect(&R, conn);
        CHECK(R.owner != conn);
        check_invariants();
        break;
    case 5:
        abbe_mb_regs_count_request(&R, fz_u8(in), (int)(fz_u8(in) % 7u));
        abbe_mb_regs_set_clients(&R, fz_u8(in), fz_u16(in));
        check_invariants();
        break;
    default: { /* the cycle trigger alone */
        uint16_t c = fz_u16(in);
        (void)do_write(conn, ABBE_MB_REG_IN_CYCLE, 1, &c);
        break;
    }
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fz_reader_t in = {data, size};
    abbe_mb_regs_config_t cfg;
    abbe_mb_regs_default_config(&cfg);
    uint8_t c0 = fz_u8(&in), c1 = fz_u8(&in);
    cfg.word_order = c0 & 1u;
    cfg.dir_source = (c0 >> 1) & 1u;
    cfg.upload_timeout_ms = (c0 & 4u) ? 0u : 1000u * (1u + (c1 & 7u));
    cfg.max_clients = (uint16_t)(1u + (c1 >> 4));
    cfg.comp.fade_cycles = (uint16_t)(1u + ((c0 >> 3) & 7u));
    cfg.comp.stale_cycles = (uint16_t)(1u + (c1 >> 5));
    const abbe_golden_table_t *t0 = &abbe_golden_tables[(c0 >> 6) % abbe_golden_table_count];
    int with_model = (c1 & 8u) != 0u;
    memset(last_corr, 0, sizeof last_corr);
    CHECK(abbe_mb_regs_init(&R, &cfg, with_model ? t0->blob : NULL, with_model ? t0->blob_size : 0u) == ABBE_OK);
    if (c0 & 0x80u) {
        uint16_t one = 1;
        CHECK(write_regs(1u, ABBE_MB_REG_CT_ENABLE, 1, &one) == 0);
    }
    n_events = 0;
    abbe_mb_regs_set_event_hook(&R, on_event, &n_events);
    abbe_mb_regs_tick(&R, 1000u);
    check_invariants();
    for (unsigned s = 0; s < MAX_STEPS && in.n > 0u; s++) {
        banks_touched |= (s % 32u) == 0u;
        switch (fz_u8(&in) % 8u) {
        case 0: step_read(&in); break;
        case 1: step_write_raw(&in); break;
        case 2:
        case 3: step_cycle(&in); break;
        case 4: step_control(&in); break;
        case 5: step_upload(&in); break;
        default: step_misc(&in); break;
        }
    }
    banks_touched = 1;
    check_invariants();
    return 0;
}
