/* libFuzzer harness: the CAN node and its frame codec (port/socketcan).
 *
 * The input is a configuration variant and then a session: frames of every
 * kind (the drives' TPDOs, SYNC, commands, temperature frames, anything with
 * any id, flags and length), model loads (golden tables, mutated or not,
 * whole or through the spare buffer), API calls, frames through the stub
 * driver and abbe_can_node_poll(), candump -l lines, all in the order the
 * bytes say (fuzz_input.h describes the encoding; make_seeds.c writes seeds).
 *
 * Checked beyond "no sanitizer report", after every step:
 *   - abbe_can_node_rx() returns a kind, never an error, and answers only a
 *     SYNC: the RPDOs (one per distinct COB-ID, the configured DLC, each
 *     axis' offset = its correction scaled, every other byte 0), the info
 *     frame when sent, and the status frame last;
 *   - the status frame says what the node says (state, model, flags with the
 *     reserved bits 0, Seq = cycle mod 256, ages, ignored count, TempStale);
 *     the info frame the model CRC and the ignored count;
 *   - every received frame is counted exactly once, in one counter;
 *   - no correction beyond its error limit; temperatures in their range;
 *   - a model load returns a documented status and queues only a valid table;
 *   - every frame sent, and every candump line that parses, survives
 *     abbe_can_log_format() -> abbe_can_log_parse() unchanged.
 */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "abbe_can.h"
#include "abbe_can_driver.h"
#include "abbe_can_log.h"
#include "fuzz_input.h"
#include "golden_data.h"

#define CHECK(cond)                                                                             \
    do {                                                                                        \
        if (!(cond)) {                                                                          \
            fprintf(stderr, "fuzz_can_node: check failed: %s (line %d)\n", #cond, __LINE__);     \
            abort();                                                                            \
        }                                                                                       \
    } while (0)

#define RESERVED_FLAGS 0xE00Cu /* flag bits no ABBE_FLAG_* defines (docs/can.md) */
#define MAX_STEPS 2000u

static abbe_can_node_t g_node;
static uint32_t g_blob_words[ABBE_CAN_BLOB_MAX / 4u]; /* 4-byte aligned, as abbe_model_load wants */
#define g_blob ((uint8_t *)g_blob_words)

/* ---- configuration variants ---------------------------------------------------- */

static void make_config(abbe_can_config_t *c, fz_reader_t *in)
{
    uint8_t v = fz_u8(in), w = fz_u8(in);
    abbe_can_config_defaults(c);
    static const double ipm[3] = {10000.0, 2000.0, 26214.4};
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        abbe_can_axis_config_t *a = &c->axis[j];
        a->node_id = (uint8_t)(j + 1u);
        a->increments_per_mm = ipm[j];
        a->warn_nm = 50000 + 10000 * (int32_t)(w & 3u);
        a->limit_nm = 2 * a->warn_nm;
        a->rate_nm_per_cycle = 500 << (w >> 6);
        a->deadband_nm = (int32_t)((w >> 2) & 3u) * 500;
        a->temp_mdegc = 20000 + 1000 * (int32_t)j;
    }
    c->temp_enable = (uint8_t)(v & 1u);
    if (v & 2u) { /* Z: statusword first, position at byte 2, DLC 8 */
        c->axis[2].tpdo_dlc = 8;
        c->axis[2].statusword_byte = 0;
        c->axis[2].position_byte = 2;
    }
    if (v & 4u) { /* X and Y share one RPDO of DLC 8 (a two-axis drive) */
        c->axis[1].rpdo_cob_id = ABBE_CAN_RPDO1_BASE + 1u;
        c->axis[0].rpdo_dlc = c->axis[1].rpdo_dlc = 8;
        c->axis[1].offset_byte = 4;
    }
    c->status_enable = (uint8_t)!(v & 8u);
    c->info_period_cycles = (uint16_t)((v & 16u) ? 3u : 0u);
    c->command_enable = (uint8_t)!(v & 32u);
    c->enable_on_start = (uint8_t)!(v & 64u);
    if (v & 128u) {
        c->axis[1].sign = -1;
        c->axis[1].origin_nm = -100000000;
        c->axis[2].correction_sign = -1;
    }
    c->stale_cycles = (uint16_t)(1u + ((w >> 4) & 3u));
    c->fade_cycles = (uint16_t)(1u + (w & 7u));
    c->temp_stale_cycles = (uint16_t)((v >> 1) & 7u);
}

/* ---- checks ---------------------------------------------------------------------- */

static uint32_t received(const abbe_can_counters_t *c)
{
    return c->syncs + c->positions + c->commands + c->temperatures + c->bad_dlc + c->unknown_id + c->rtr +
           c->error_frames + c->bad_command + c->bad_value;
}

static void check_round_trip(const abbe_can_frame_t *f, uint64_t sec, uint32_t usec)
{
    abbe_can_log_entry_t e, back;
    memset(&e, 0, sizeof e);
    e.sec = sec;
    e.usec = usec % 1000000u;
    memcpy(e.ifname, "can0", 5);
    e.frame = *f;
    char line[128];
    int len = abbe_can_log_format(&e, line, sizeof line);
    CHECK(len > 0 && (size_t)len == strlen(line) && line[len - 1] == '\n');
    CHECK(abbe_can_log_parse(line, &back) == ABBE_CAN_OK);
    CHECK(back.sec == e.sec && back.usec == e.usec && strcmp(back.ifname, "can0") == 0);
    CHECK(back.frame.id == f->id && back.frame.dlc == f->dlc);
    if (!(f->id & ABBE_CAN_RTR_FLAG)) {
        CHECK(memcmp(back.frame.data, f->data, f->dlc) == 0);
    }
}

static void check_state(const abbe_can_node_t *n)
{
    abbe_can_counters_t c = abbe_can_node_counters(n);
    CHECK(received(&c) == c.frames_rx);
    CHECK(abbe_can_node_ignored(n) ==
          c.bad_dlc + c.unknown_id + c.rtr + c.error_frames + c.bad_command + c.bad_value + c.malformed);
    const abbe_can_config_t *cfg = abbe_can_node_config(n);
    const abbe_comp_output_t *out = abbe_can_node_output(n);
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        CHECK(out->corr_nm[j] <= cfg->axis[j].limit_nm && out->corr_nm[j] >= -cfg->axis[j].limit_nm);
        int32_t t = abbe_can_node_temp_mdegc(n, j);
        CHECK(t == cfg->axis[j].temp_mdegc ||
              (t >= 10 * ABBE_CAN_TEMP_MIN_CDEGC && t <= 10 * ABBE_CAN_TEMP_MAX_CDEGC && t % 10 == 0));
    }
    CHECK(!abbe_can_node_temp_stale(n) || cfg->temp_enable);
    int ls = abbe_can_node_last_load_status(n);
    CHECK(ls == 0 || (ls >= ABBE_STATUS_MIN && ls < 0) || ls == ABBE_CAN_E_IO || ls == ABBE_CAN_E_BUSY ||
          ls == ABBE_CAN_E_TOO_BIG);
    CHECK(strncmp(abbe_can_status_name(ls), "ABBE_", 5) == 0);
}

/* The frames one SYNC produced. */
static void check_cycle(const abbe_can_node_t *n, const abbe_can_frame_t *tx, size_t n_tx)
{
    const abbe_can_config_t *cfg = abbe_can_node_config(n);
    const abbe_comp_output_t *out = abbe_can_node_output(n);
    CHECK(n_tx <= ABBE_CAN_MAX_TX);
    size_t k = 0;
    /* the RPDOs, in axis order of their first axis */
    uint32_t ids[ABBE_AXES];
    size_t n_ids = 0;
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        size_t i = 0;
        while (i < n_ids && ids[i] != cfg->axis[j].rpdo_cob_id) {
            i++;
        }
        if (i == n_ids) {
            ids[n_ids++] = cfg->axis[j].rpdo_cob_id;
        }
    }
    for (size_t i = 0; i < n_ids; i++, k++) {
        CHECK(k < n_tx && tx[k].id == ids[i]);
        uint8_t covered[ABBE_CAN_MAX_DLEN] = {0};
        for (unsigned j = 0; j < ABBE_AXES; j++) {
            const abbe_can_axis_config_t *a = &cfg->axis[j];
            if (a->rpdo_cob_id != ids[i]) {
                continue;
            }
            CHECK(tx[k].dlc == a->rpdo_dlc);
            CHECK(abbe_can_get_i32(&tx[k].data[a->offset_byte]) == abbe_can_nm_to_incr(a, out->corr_nm[j]));
            memset(&covered[a->offset_byte], 1, 4);
        }
        for (unsigned b = 0; b < ABBE_CAN_MAX_DLEN; b++) {
            CHECK(covered[b] || tx[k].data[b] == 0u);
        }
    }
    uint32_t ignored = abbe_can_node_ignored(n);
    if (k < n_tx && cfg->info_period_cycles > 0u && tx[k].id == cfg->info_cob_id) {
        abbe_can_info_frame_t info;
        CHECK(cfg->info_period_cycles > 0u);
        CHECK(abbe_can_info_decode(&tx[k], &info) == ABBE_CAN_OK);
        CHECK(info.model_crc == abbe_can_node_model_crc(n));
        CHECK(info.ignored == (ignored > 0xFFFFu ? 0xFFFFu : ignored));
        CHECK(info.load_status == (int8_t)abbe_can_node_last_load_status(n) ||
              abbe_can_node_last_load_status(n) < -128);
        CHECK(info.model_swaps == (uint8_t)(abbe_can_node_comp_stats(n).model_swaps & 0xFFu));
        k++;
    }
    if (cfg->status_enable) {
        abbe_can_status_frame_t st;
        CHECK(k + 1u == n_tx && tx[k].id == cfg->status_cob_id);
        CHECK(abbe_can_status_decode(&tx[k], &st) == ABBE_CAN_OK);
        CHECK(st.state == (uint8_t)out->state);
        CHECK(st.model_loaded == (abbe_comp_model(&n->comp) != NULL));
        CHECK(st.load_failed == (abbe_can_node_last_load_status(n) != 0));
        CHECK(st.flags == (uint16_t)(out->flags & 0xFFFFu) && (st.flags & RESERVED_FLAGS) == 0u);
        CHECK(st.seq == (uint8_t)((abbe_can_node_counters(n).syncs - 1u) & 0xFFu));
        CHECK(st.ignored == (uint8_t)(ignored & 0xFFu));
        CHECK(st.temp_stale == (uint8_t)abbe_can_node_temp_stale(n));
        for (unsigned j = 0; j < ABBE_AXES; j++) {
            uint32_t age = abbe_can_node_age(n, j);
            CHECK(st.age[j] == (age >= 255u ? 255u : age));
            CHECK(((st.fresh_mask >> j) & 1u) == (age == 0u));
        }
        k++;
    }
    CHECK(k == n_tx);
}

static void rx_checked(abbe_can_node_t *n, const abbe_can_frame_t *f, uint64_t stamp)
{
    abbe_can_frame_t tx[ABBE_CAN_MAX_TX];
    size_t n_tx = 99;
    abbe_can_counters_t before = abbe_can_node_counters(n);
    int kind = abbe_can_node_rx(n, f, tx, &n_tx);
    CHECK(kind >= ABBE_CAN_RX_SYNC && kind <= ABBE_CAN_RX_BAD_VALUE);
    abbe_can_counters_t after = abbe_can_node_counters(n);
    CHECK(after.frames_rx == before.frames_rx + 1u);
    CHECK(received(&after) == received(&before) + 1u);
    if (kind == ABBE_CAN_RX_SYNC) {
        CHECK(after.syncs == before.syncs + 1u);
        check_cycle(n, tx, n_tx);
        /* TempStale as docs/can.md defines it, from the ages at this SYNC */
        const abbe_can_config_t *cfg = abbe_can_node_config(n);
        uint32_t limit = cfg->temp_stale_cycles, frame_age = abbe_can_node_temp_age(n, ABBE_AXES);
        int stale = cfg->temp_enable && (frame_age == UINT32_MAX || (limit > 0u && frame_age >= limit));
        for (unsigned j = 0; j < ABBE_AXES; j++) {
            uint32_t age = abbe_can_node_temp_age(n, j);
            stale |= cfg->temp_enable && age != UINT32_MAX && limit > 0u && age >= limit;
            CHECK(age == UINT32_MAX || frame_age <= age);
        }
        CHECK(abbe_can_node_temp_stale(n) == stale);
        for (size_t i = 0; i < n_tx; i++) {
            check_round_trip(&tx[i], stamp, (uint32_t)(stamp * 7919u));
        }
    } else {
        CHECK(n_tx == 0u);
    }
    check_state(n);
}

/* ---- steps ----------------------------------------------------------------------------- */

static abbe_can_frame_t frame_of(uint32_t id, uint8_t dlc, fz_reader_t *in)
{
    abbe_can_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = id;
    f.dlc = dlc;
    fz_bytes(in, f.data, sizeof f.data);
    return f;
}

static void step_model(abbe_can_node_t *n, fz_reader_t *in)
{
    const abbe_golden_table_t *t = &abbe_golden_tables[fz_u8(in) % abbe_golden_table_count];
    size_t size = t->blob_size;
    uint8_t how = fz_u8(in);
    memcpy(g_blob, t->blob, size);
    for (unsigned m = 0; m < (how & 3u); m++) { /* a few bytes changed */
        uint16_t at = fz_u16(in);
        g_blob[at % size] ^= fz_u8(in);
    }
    if (how & 4u) { /* a changed total_size / truncation */
        size = size - (fz_u8(in) % 64u);
    }
    if (how & 8u) { /* CRC fixed up so the mutation reaches the checks behind it */
        uint32_t total = abbe_can_get_u32(g_blob + 8);
        if (total >= 8u && total <= size) {
            abbe_can_put_u32(g_blob + total - 4u, abbe_crc32(0u, g_blob, total - 4u));
        }
    }
    int pending = abbe_can_node_model_pending(n);
    uint32_t crc_before = abbe_can_node_model_crc(n);
    int st;
    size_t used = size;
    if (how & 16u) { /* fill the spare buffer and commit (the embedded way) */
        size_t cap = 0;
        uint8_t *buf = abbe_can_node_model_buffer(n, &cap);
        CHECK((buf == NULL) == (pending != 0));
        if (buf == NULL) {
            st = abbe_can_node_commit_model(n, size);
            CHECK(st == ABBE_CAN_E_BUSY);
        } else {
            CHECK(cap == ABBE_CAN_BLOB_MAX);
            memcpy(buf, g_blob, size);
            size_t claim = (how & 32u) ? (size_t)fz_u16(in) : size; /* a wrong size, maybe > cap */
            st = abbe_can_node_commit_model(n, claim);
            used = claim;
            CHECK(claim <= ABBE_CAN_BLOB_MAX || st == ABBE_CAN_E_TOO_BIG);
        }
    } else {
        st = abbe_can_node_load_model(n, g_blob, size);
    }
    if (pending) {
        CHECK(st == ABBE_CAN_E_BUSY);
    }
    CHECK(st == ABBE_CAN_OK || st == ABBE_CAN_E_BUSY || st == ABBE_CAN_E_TOO_BIG ||
          (st >= ABBE_STATUS_MIN && st < 0));
    CHECK(abbe_can_node_last_load_status(n) == st);
    CHECK(abbe_can_node_model_pending(n) == (st == ABBE_CAN_OK || pending));
    CHECK(abbe_can_node_model_crc(n) == crc_before); /* the running model is untouched until a SYNC */
    if (st == ABBE_CAN_OK && used == size) { /* what was queued is a valid table */
        abbe_model_t m;
        CHECK(abbe_model_load(&m, g_blob, size) == ABBE_OK);
    }
}

static void step_api(abbe_can_node_t *n, fz_reader_t *in)
{
    switch (fz_u8(in) % 8u) {
    case 0: CHECK(abbe_can_node_enable(n) == ABBE_OK); break;
    case 1: CHECK(abbe_can_node_disable(n) == ABBE_OK); break;
    case 2: CHECK(abbe_can_node_reset(n) == ABBE_OK); break;
    case 3:
        abbe_can_node_request_reload(n);
        CHECK(abbe_can_node_take_reload_request(n) == 1);
        CHECK(abbe_can_node_take_reload_request(n) == 0);
        break;
    case 4: abbe_can_node_note_load_failure(n, ABBE_CAN_E_IO); break;
    case 5: abbe_can_node_count_malformed(n); break;
    case 6: abbe_can_node_count_tx_error(n); break;
    default: (void)abbe_can_node_take_reload_request(n); break;
    }
    check_state(n);
}

/* Frames through the stub target and abbe_can_node_poll(). */
static void step_poll(abbe_can_node_t *n, fz_reader_t *in)
{
    static abbe_can_stub_t stub;
    abbe_can_driver_t drv;
    abbe_can_stub_init(&stub, &drv);
    unsigned count = fz_u8(in) % 8u;
    unsigned syncs = 0, reload_at = count;
    const abbe_can_config_t *cfg = abbe_can_node_config(n);
    for (unsigned i = 0; i < count; i++) {
        uint8_t what = fz_u8(in);
        abbe_can_frame_t f;
        if (what & 1u) {
            f = frame_of(cfg->sync_cob_id, 0, in);
            syncs++;
        } else if (what & 2u) {
            f = frame_of(cfg->axis[(what >> 2) % ABBE_AXES].tpdo_cob_id, cfg->axis[(what >> 2) % ABBE_AXES].tpdo_dlc, in);
        } else {
            f = frame_of(cfg->command_cob_id, 1, in);
            if (cfg->command_enable && f.data[0] == ABBE_CAN_CMD_RELOAD && reload_at == count) {
                reload_at = i;
            }
        }
        CHECK(abbe_can_stub_inject(&stub, &f) == ABBE_CAN_OK);
    }
    uint32_t rx_before = abbe_can_node_counters(n).frames_rx;
    int handled = abbe_can_node_poll(n, &drv, 1000u);
    /* everything, or up to and including the first RELOAD command */
    CHECK(handled == (int)(reload_at < count ? reload_at + 1u : count));
    CHECK(abbe_can_node_counters(n).frames_rx == rx_before + (uint32_t)handled);
    (void)syncs;
    abbe_can_frame_t f;
    while (abbe_can_stub_take(&stub, &f) == ABBE_CAN_OK) {
        CHECK(f.dlc <= ABBE_CAN_MAX_DLEN);
    }
    (void)abbe_can_node_take_reload_request(n);
    check_state(n);
}

/* A candump -l line from the input: if it parses, its frame formats and
 * parses back to the same entry. */
static void step_log_line(fz_reader_t *in)
{
    char line[128];
    size_t len = fz_u8(in) % (sizeof line - 1u);
    fz_bytes(in, (uint8_t *)line, len);
    line[len] = '\0';
    abbe_can_log_entry_t e;
    int st = abbe_can_log_parse(line, &e);
    CHECK(st == ABBE_CAN_OK || st == ABBE_CAN_E_PARSE || st == ABBE_CAN_E_UNSUPPORTED);
    if (st != ABBE_CAN_OK) {
        return;
    }
    CHECK(e.frame.dlc <= ABBE_CAN_MAX_DLEN && e.usec < 1000000u && strlen(e.ifname) > 0u);
    char out[128];
    int n = abbe_can_log_format(&e, out, sizeof out);
    CHECK(n > 0);
    abbe_can_log_entry_t back;
    CHECK(abbe_can_log_parse(out, &back) == ABBE_CAN_OK);
    CHECK(back.sec == e.sec && back.usec == e.usec && strcmp(back.ifname, e.ifname) == 0);
    CHECK(back.frame.id == e.frame.id && back.frame.dlc == e.frame.dlc);
    if (!(e.frame.id & ABBE_CAN_RTR_FLAG)) {
        CHECK(memcmp(back.frame.data, e.frame.data, e.frame.dlc) == 0);
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fz_reader_t in = {data, size};
    abbe_can_config_t cfg;
    make_config(&cfg, &in);
    abbe_can_node_t *n = &g_node;
    CHECK(abbe_can_node_init(n, &cfg) == ABBE_CAN_OK);
    const abbe_can_config_t *rc = abbe_can_node_config(n);
    if (fz_u8(&in) & 1u) {
        const abbe_golden_table_t *t = &abbe_golden_tables[0];
        CHECK(abbe_can_node_load_model(n, t->blob, t->blob_size) == ABBE_CAN_OK);
    }
    uint64_t stamp = 1700000000u;
    for (unsigned s = 0; s < MAX_STEPS && in.n > 0u; s++, stamp++) {
        uint8_t op = fz_u8(&in);
        switch (op % 10u) {
        case 0:
        case 1: { /* a drive's TPDO: usually well formed, with positions near the origin or anywhere */
            const abbe_can_axis_config_t *a = &rc->axis[fz_u8(&in) % ABBE_AXES];
            uint8_t dlc = (op & 0x80u) ? (uint8_t)(fz_u8(&in) % 16u) : a->tpdo_dlc;
            abbe_can_frame_t f = frame_of(a->tpdo_cob_id, dlc, &in);
            if (op & 0x40u) { /* small moves: realistic positions, exercises direction and take-up */
                abbe_can_put_i32(&f.data[a->position_byte], (int32_t)(int16_t)abbe_can_get_u16(&f.data[a->position_byte]) * 64);
            }
            rx_checked(n, &f, stamp);
            break;
        }
        case 2: { /* SYNC: no data, the counter byte, or too long */
            uint8_t dlc = (op & 0x80u) ? (uint8_t)(fz_u8(&in) % 4u) : (uint8_t)((op >> 4) & 1u);
            abbe_can_frame_t f = frame_of(rc->sync_cob_id, dlc, &in);
            rx_checked(n, &f, stamp);
            break;
        }
        case 3: { /* command */
            uint8_t dlc = (op & 0x80u) ? (uint8_t)(fz_u8(&in) % 3u) : 1u;
            abbe_can_frame_t f = frame_of(rc->command_cob_id, dlc, &in);
            if (!(op & 0x40u)) {
                f.data[0] = (uint8_t)(f.data[0] % 6u);
            }
            rx_checked(n, &f, stamp);
            (void)abbe_can_node_take_reload_request(n);
            break;
        }
        case 4: { /* temperature frame: readings in range, no reading, or raw */
            uint8_t dlc = (op & 0x80u) ? (uint8_t)(fz_u8(&in) % 9u) : ABBE_CAN_TEMP_DLC;
            abbe_can_frame_t f = frame_of(rc->temp_cob_id, dlc, &in);
            if (!(op & 0x40u)) {
                for (unsigned j = 0; j < ABBE_AXES; j++) {
                    uint16_t u = abbe_can_get_u16(&f.data[2u * j]);
                    int32_t v = (u & 1u) ? ABBE_CAN_TEMP_NO_READING
                                         : ABBE_CAN_TEMP_MIN_CDEGC +
                                               (int32_t)((unsigned)u % (unsigned)(ABBE_CAN_TEMP_MAX_CDEGC -
                                                                                  ABBE_CAN_TEMP_MIN_CDEGC + 1));
                    abbe_can_put_u16(&f.data[2u * j], (uint16_t)(v < 0 ? v + 65536 : v));
                }
            }
            rx_checked(n, &f, stamp);
            break;
        }
        case 5: { /* any frame at all */
            uint32_t id = fz_u32(&in);
            if (op & 0x80u) {
                id &= ABBE_CAN_SFF_MASK;
            }
            abbe_can_frame_t f = frame_of(id, (uint8_t)(fz_u8(&in) % 16u), &in);
            rx_checked(n, &f, stamp);
            break;
        }
        case 6: step_model(n, &in); break;
        case 7: step_api(n, &in); break;
        case 8: step_poll(n, &in); break;
        default: step_log_line(&in); break;
        }
    }
    return 0;
}
