/* abbe Modbus port: register map engine (docs/modbus-registers.md).
 *
 * Tables live in three banks: the running one, the one queued for the next
 * cycle, and the staging bank the host writes into. A commit validates the
 * staging bank in place and queues it (abbe_comp_load_model), so the running
 * model is never touched by an upload and the swap happens at a cycle
 * boundary, inside abbe_comp_step_q(). Every request is checked as a whole
 * before anything changes.
 */
#include <stddef.h>
#include <string.h>

#include "abbe/modbus_port.h"

/* abbe_model_load() reads the coefficients in place and refuses a blob that is
 * not 4-byte aligned (ABBE_E_ALIGN): every bank must be, and is, since the
 * struct is aligned for its uint32_t members. */
typedef char abbe_mb_bank_align_check[(offsetof(abbe_mb_regs_t, bank) % 4u == 0u &&
                                       ABBE_MB_STAGING_MAX % 4 == 0) ? 1 : -1];

#define STAGING_REGS ((uint32_t)ABBE_MB_STAGING_MAX / 2u)
#define MAX_READ 125u
#define MAX_WRITE 123u

enum { BLK_ID, BLK_ST, BLK_UP, BLK_IN, BLK_OUT, BLK_CT, BLK_TIN, BLK_TOUT, BLK_STAGING, BLK_NONE };

typedef struct {
    uint16_t base;
    uint16_t count;
} block_t;

static const block_t blocks[BLK_STAGING] = {
    {ABBE_MB_REG_ID_BASE, ABBE_MB_ID_COUNT}, {ABBE_MB_REG_ST_BASE, ABBE_MB_ST_COUNT},
    {ABBE_MB_REG_UP_BASE, ABBE_MB_UP_COUNT}, {ABBE_MB_REG_IN_BASE, ABBE_MB_IN_COUNT},
    {ABBE_MB_REG_OUT_BASE, ABBE_MB_OUT_COUNT}, {ABBE_MB_REG_CT_BASE, ABBE_MB_CT_COUNT},
    {ABBE_MB_REG_TIN_BASE, ABBE_MB_TIN_COUNT}, {ABBE_MB_REG_TOUT_BASE, ABBE_MB_TOUT_COUNT},
};

/* The largest block, for the render buffer. */
#define BLOCK_MAX 32u

/* Block holding all of [addr, addr + count), or BLK_NONE. */
static int find_block(uint16_t addr, uint16_t count)
{
    uint32_t end = (uint32_t)addr + count;
    for (int b = 0; b < BLK_STAGING; b++) {
        if (addr >= blocks[b].base && end <= (uint32_t)blocks[b].base + blocks[b].count) {
            return b;
        }
    }
    if (addr >= ABBE_MB_REG_STAGING && end <= ABBE_MB_REG_STAGING + STAGING_REGS) {
        return BLK_STAGING;
    }
    return BLK_NONE;
}

/* ---- 32-bit values in two registers ---------------------------------------- */

static void put32(const abbe_mb_regs_t *r, uint16_t *dst, uint32_t v)
{
    uint16_t hi = (uint16_t)(v >> 16), lo = (uint16_t)(v & 0xFFFFu);
    dst[0] = r->word_order == ABBE_MB_WORD_ORDER_LOW_FIRST ? lo : hi;
    dst[1] = r->word_order == ABBE_MB_WORD_ORDER_LOW_FIRST ? hi : lo;
}

/* src[0] and src[1] are both written: abbe_mb_regs_write refuses a write that
 * starts or ends inside a pair (pair_second), which clang-analyzer does not
 * follow into write_inputs / write_control (docs/misra.md). */
static uint32_t get32(const abbe_mb_regs_t *r, const uint16_t *src)
{
    if (r->word_order == ABBE_MB_WORD_ORDER_LOW_FIRST) {
        return ((uint32_t)src[1] << 16) | src[0]; /* NOLINT(clang-analyzer-core.UndefinedBinaryOperatorResult) */
    }
    return ((uint32_t)src[0] << 16) | src[1]; /* NOLINT(clang-analyzer-core.UndefinedBinaryOperatorResult) */
}

static uint32_t from_i32(int32_t v)
{
    return (uint32_t)v; /* two's complement bit pattern, defined for all values */
}

static int32_t to_i32(uint32_t v)
{
    return v <= (uint32_t)INT32_MAX ? (int32_t)v : (int32_t)(v - 0x80000000u) + INT32_MIN;
}

static int16_t to_i16(uint16_t v)
{
    /* NOLINTNEXTLINE(bugprone-narrowing-conversions): both branches are in int16_t range */
    return v <= (uint16_t)INT16_MAX ? (int16_t)v : (int16_t)((int32_t)v - 65536);
}

static uint16_t from_i16(int16_t v)
{
    return (uint16_t)(v < 0 ? (int32_t)v + 65536 : (int32_t)v);
}

/* Is addr the second register of a 32-bit value in a writable block? */
static int pair_second(uint16_t addr)
{
    if (addr > ABBE_MB_REG_IN_POS_X && addr <= ABBE_MB_REG_IN_POS_Z + 1u) {
        return ((addr - ABBE_MB_REG_IN_POS_X) & 1u) != 0u;
    }
    if (addr > ABBE_MB_REG_CT_WARN_X && addr <= ABBE_MB_REG_CT_RATE_Z + 1u) {
        return ((addr - ABBE_MB_REG_CT_WARN_X) & 1u) != 0u;
    }
    if (addr == ABBE_MB_REG_IN_TH_DT_MS + 1u) {
        return 1;
    }
    return 0;
}

/* ---- model bookkeeping -------------------------------------------------------- */

static uint32_t model_crc_or_0(const abbe_model_t *m)
{
    return m != NULL ? abbe_model_crc(m) : 0u;
}

static int8_t free_bank(const abbe_mb_regs_t *r)
{
    for (int8_t i = 0; i < ABBE_MB_BANKS; i++) {
        if (i != r->running && i != r->pending) {
            return i;
        }
    }
    return -1; /* not reached: three banks, at most two in use */
}

static abbe_comp_stats_t stats_sum(const abbe_mb_regs_t *r)
{
    abbe_comp_stats_t s = abbe_comp_stats(&r->comp), b = r->stats_base;
    s.cycles += b.cycles;
    s.invalid_inputs += b.invalid_inputs;
    s.stale_events += b.stale_events;
    s.limit_trips += b.limit_trips;
    s.rate_limited += b.rate_limited;
    s.model_swaps += b.model_swaps;
    return s;
}

/* ---- upload session ------------------------------------------------------------ */

static void emit(const abbe_mb_regs_t *r, abbe_mb_event_kind_t kind, uint32_t conn, int16_t result,
                 uint32_t size, uint32_t crc)
{
    if (r->event_fn == NULL) {
        return;
    }
    abbe_mb_event_t ev;
    memset(&ev, 0, sizeof ev);
    ev.kind = kind;
    ev.conn = conn;
    ev.owner = r->owner;
    ev.session = r->session;
    ev.result = result;
    ev.cycle = r->cycle_in;
    ev.size = size;
    ev.crc = crc;
    r->event_fn(r->event_ctx, &ev);
}

static void session_close(abbe_mb_regs_t *r, int16_t result)
{
    uint32_t owner = r->owner;
    uint32_t size = result == ABBE_MB_UP_OK ? r->commit_len : 0u;
    uint32_t crc = result == ABBE_MB_UP_OK ? r->model_crc : 0u;
    r->owner = 0;
    r->staging = -1;
    r->filled = 0;
    r->result = result;
    if (result != ABBE_MB_UP_OK) {
        r->uploads_rejected++;
    }
    emit(r, ABBE_MB_EV_UPLOAD_END, owner, result, size, crc);
}

/* No session: wrong state. Someone else's: busy. */
static int session_check(const abbe_mb_regs_t *r, uint32_t conn)
{
    if (r->owner == 0u) {
        return ABBE_MB_EX_ILLEGAL_FUNCTION;
    }
    return r->owner == conn ? 0 : ABBE_MB_EX_BUSY;
}

static int upload_begin(abbe_mb_regs_t *r, uint32_t conn)
{
    if (r->owner != 0u && r->owner != conn) {
        r->uploads_rejected++;
        emit(r, ABBE_MB_EV_UPLOAD_BUSY, conn, 0, 0, 0);
        return ABBE_MB_EX_BUSY;
    }
    if (r->owner == conn) {
        session_close(r, ABBE_MB_UP_ABORTED);
    }
    r->staging = free_bank(r);
    memset(r->bank[r->staging], 0, sizeof r->bank[0]);
    r->owner = conn;
    r->filled = 0;
    r->session = (uint16_t)(r->session == UINT16_MAX ? 1u : r->session + 1u);
    r->result = ABBE_MB_UP_NONE;
    r->last_activity_ms = r->now_ms;
    emit(r, ABBE_MB_EV_UPLOAD_BEGIN, conn, 0, 0, 0);
    return 0;
}

static int upload_commit(abbe_mb_regs_t *r, uint32_t conn, uint32_t len, uint32_t crc)
{
    int ex = session_check(r, conn);
    if (ex != 0) {
        return ex;
    }
    r->commit_len = len;
    r->commit_crc = crc;
    r->rx_crc = 0;
    if (len == 0u || len > (uint32_t)ABBE_MB_STAGING_MAX) {
        session_close(r, ABBE_MB_UP_LENGTH);
        return ABBE_MB_EX_ILLEGAL_VALUE;
    }
    if (len > r->filled) {
        session_close(r, ABBE_MB_UP_INCOMPLETE);
        return ABBE_MB_EX_ILLEGAL_VALUE;
    }
    int8_t s = r->staging;
    r->rx_crc = abbe_crc32(0u, r->bank[s], len);
    if (r->rx_crc != crc) {
        session_close(r, ABBE_MB_UP_CRC_MISMATCH);
        return ABBE_MB_EX_ILLEGAL_VALUE;
    }
    /* abbe_thermal_load: every check of abbe_model_load, and format 1.3's thermal block */
    abbe_status_t st = abbe_thermal_load(&r->slot[s], &r->thermal[s], r->bank[s], len);
    if (st == ABBE_OK) {
        st = abbe_comp_swap_model(&r->comp, &r->slot[s]);
    }
    if (st != ABBE_OK) {
        session_close(r, (int16_t)st);
        return ABBE_MB_EX_ILLEGAL_VALUE;
    }
    r->pending = s;
    r->model_crc = abbe_model_crc(&r->slot[s]);
    r->uploads_ok++;
    session_close(r, ABBE_MB_UP_OK);
    return 0;
}

static int write_upload(abbe_mb_regs_t *r, uint32_t conn, uint16_t addr, uint16_t count,
                        const uint16_t *v)
{
    if (addr == ABBE_MB_REG_UP_CMD && count == 1u) {
        if (v[0] == ABBE_MB_UP_CMD_BEGIN) {
            return upload_begin(r, conn);
        }
        if (v[0] == ABBE_MB_UP_CMD_ABORT) {
            int ex = session_check(r, conn);
            if (ex == 0) {
                session_close(r, ABBE_MB_UP_ABORTED);
            }
            return ex;
        }
        return ABBE_MB_EX_ILLEGAL_VALUE;
    }
    if (addr == ABBE_MB_REG_UP_COMMIT && count == 4u) {
        return upload_commit(r, conn, get32(r, &v[0]), get32(r, &v[2]));
    }
    return ABBE_MB_EX_ILLEGAL_ADDRESS;
}

static int write_staging(abbe_mb_regs_t *r, uint32_t conn, uint16_t addr, uint16_t count,
                         const uint8_t *values_be)
{
    int ex = session_check(r, conn);
    if (ex != 0) {
        return ex;
    }
    uint32_t off = 2u * (uint32_t)(addr - ABBE_MB_REG_STAGING);
    uint32_t end = off + 2u * count;
    if (off > r->filled) {
        return ABBE_MB_EX_ILLEGAL_ADDRESS; /* would leave a gap: chunks go in order */
    }
    memcpy(&r->bank[r->staging][off], values_be, 2u * (size_t)count);
    if (end > r->filled) {
        r->filled = end;
    }
    r->last_activity_ms = r->now_ms;
    return 0;
}

/* ---- the cycle -------------------------------------------------------------------- */

/* The thermal state of the table that runs next (started afresh for a new
 * table: it fades in after its first good sample); NULL without a block. */
static abbe_thermal_state_t *thermal_state(abbe_mb_regs_t *r)
{
    int8_t b = (int8_t)(r->pending >= 0 ? r->pending : r->running);
    if (b < 0 || r->thermal[b].n_channels == 0u) {
        r->th_bank = -1;
        return NULL;
    }
    if (b != r->th_bank) {
        (void)abbe_thermal_init_q(&r->th, &r->thermal[b], r->cycle_us);
        r->th_bank = b;
    }
    return &r->th;
}

static void run_cycle(abbe_mb_regs_t *r)
{
    abbe_comp_input_q_t in;
    uint8_t fresh = r->pos_written == 0x7u;
    memset(&in, 0, sizeof in);
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        in.pos_nm[j] = r->pos_nm[j];
        in.temp_mdegc[j] = 10 * (int32_t)r->temp_cdegc[j];
        if (r->dir_source) {
            int32_t d = 0;
            if (fresh && r->have_last_pos) {
                d = r->pos_nm[j] > r->last_pos_nm[j] ? 1 : (r->pos_nm[j] < r->last_pos_nm[j] ? -1 : 0);
            }
            in.dir[j] = (int8_t)d;
        } else {
            in.dir[j] = (int8_t)r->dir[j];
        }
    }
    in.fresh = fresh;
    in.axis_fault_mask = (uint8_t)r->axis_fault;
    (void)abbe_comp_step_thermal_q(&r->comp, thermal_state(r), &in, &r->out); /* only fails for NULL pointers */
    if (fresh) {
        memcpy(r->last_pos_nm, r->pos_nm, sizeof r->last_pos_nm);
        r->have_last_pos = 1;
    }
    r->pos_written = 0;
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        /* target = -sign * error, clamped to +/-INT32_MAX, so this is exact */
        r->err_nm[j] = r->comp_cfg.axis_sign[j] > 0 ? -r->out.target_nm[j] : r->out.target_nm[j];
    }
    r->out_cycle = r->cycle_in;
    if (r->pending >= 0 && abbe_comp_model(&r->comp) == &r->slot[r->pending]) {
        r->running = r->pending;
        r->pending = -1;
        const abbe_model_t *m = &r->slot[r->running];
        emit(r, ABBE_MB_EV_MODEL_SWAP, 0, 0, abbe_model_size(m), abbe_model_crc(m));
    }
}

static int write_inputs(abbe_mb_regs_t *r, uint16_t addr, uint16_t count, const uint16_t *v)
{
    int32_t pos[ABBE_AXES];
    int16_t dir[ABBE_AXES], temp[ABBE_AXES];
    uint16_t fault = r->axis_fault, cycle = r->cycle_in;
    uint8_t written = 0, trigger = 0;
    memcpy(pos, r->pos_nm, sizeof pos);
    memcpy(dir, r->dir, sizeof dir);
    memcpy(temp, r->temp_cdegc, sizeof temp);

    for (uint16_t i = 0; i < count; i++) {
        uint16_t a = (uint16_t)(addr + i);
        if (a < ABBE_MB_REG_IN_DIR_X) {
            unsigned j = (unsigned)(a - ABBE_MB_REG_IN_POS_X) / 2u;
            if (((a - ABBE_MB_REG_IN_POS_X) & 1u) == 0u) {
                pos[j] = to_i32(get32(r, &v[i]));
                written |= (uint8_t)(1u << j);
            }
        } else if (a <= ABBE_MB_REG_IN_DIR_Z) {
            int16_t d = to_i16(v[i]);
            if (d < -1 || d > 1) {
                return ABBE_MB_EX_ILLEGAL_VALUE;
            }
            dir[a - ABBE_MB_REG_IN_DIR_X] = d;
        } else if (a <= ABBE_MB_REG_IN_TEMP_Z) {
            int16_t t = to_i16(v[i]);
            if (t == ABBE_MB_TEMP_NO_READING) {
                continue; /* no reading: keep the axis' temperature */
            }
            if (t < ABBE_MB_TEMP_MIN_CDEGC || t > ABBE_MB_TEMP_MAX_CDEGC) {
                return ABBE_MB_EX_ILLEGAL_VALUE;
            }
            temp[a - ABBE_MB_REG_IN_TEMP_X] = t;
        } else if (a == ABBE_MB_REG_IN_AXIS_FAULT) {
            if (v[i] > 7u) {
                return ABBE_MB_EX_ILLEGAL_VALUE;
            }
            fault = v[i];
        } else {
            cycle = v[i];
            trigger = 1;
        }
    }
    memcpy(r->pos_nm, pos, sizeof pos);
    memcpy(r->dir, dir, sizeof dir);
    memcpy(r->temp_cdegc, temp, sizeof temp);
    r->axis_fault = fault;
    r->cycle_in = cycle;
    r->pos_written |= written;
    if (trigger) {
        run_cycle(r);
    }
    return 0;
}

/* IN_TH_*: every value is taken (the runtime judges the readings); the
 * reserved register must be 0, IN_TH_DT_MS 1 .. 2^31. */
static int write_thermal(abbe_mb_regs_t *r, uint16_t addr, uint16_t count, const uint16_t *v)
{
    int16_t in[ABBE_MB_TH_INPUTS];
    uint32_t dt = r->th_dt_ms;
    uint16_t echo = r->th_echo;
    uint8_t trigger = 0;
    memcpy(in, r->th_in, sizeof in);
    for (uint16_t i = 0; i < count; i++) {
        uint16_t a = (uint16_t)(addr + i);
        if (a < ABBE_MB_REG_IN_TH_RESERVED) {
            in[a - ABBE_MB_REG_IN_TH_0] = to_i16(v[i]);
        } else if (a == ABBE_MB_REG_IN_TH_RESERVED) {
            if (v[i] != 0u) {
                return ABBE_MB_EX_ILLEGAL_VALUE;
            }
        } else if (a == ABBE_MB_REG_IN_TH_DT_MS) {
            dt = get32(r, &v[i]);
            if (dt < 1u || dt > 0x80000000u) {
                return ABBE_MB_EX_ILLEGAL_VALUE;
            }
        } else if (a == ABBE_MB_REG_IN_TH_SAMPLE) {
            echo = v[i];
            trigger = 1;
        }
    }
    memcpy(r->th_in, in, sizeof in);
    r->th_dt_ms = dt;
    r->th_echo = echo;
    abbe_thermal_state_t *th = trigger ? thermal_state(r) : NULL;
    if (th != NULL) {
        const abbe_thermal_model_t *tm = &r->thermal[r->th_bank];
        int32_t x[ABBE_MB_TH_INPUTS];
        uint32_t valid = 0;
        for (unsigned k = 0; k < ABBE_MB_TH_INPUTS; k++) {
            x[k] = tm->kind[k] == ABBE_THERMAL_SPEED ? in[k] : 10 * (int32_t)in[k]; /* rpm; m degC */
            valid |= in[k] != ABBE_MB_TEMP_NO_READING ? 1u << k : 0u;
        }
        (void)abbe_thermal_update_q(th, x, valid, dt);
        r->th_samples++;
    }
    return 0;
}

/* ---- control ------------------------------------------------------------------------ */

static int write_control(abbe_mb_regs_t *r, uint16_t addr, uint16_t count, const uint16_t *v)
{
    abbe_comp_config_t cfg = r->comp_cfg;
    int enable = -1, reset = 0, word_order = r->word_order, dir_source = r->dir_source;
    int limits = 0;

    for (uint16_t i = 0; i < count; i++) {
        uint16_t a = (uint16_t)(addr + i);
        uint16_t x = v[i];
        if (a >= ABBE_MB_CT_FIRST_LIMIT) {
            limits = 1;
        }
        if (a == ABBE_MB_REG_CT_ENABLE || a == ABBE_MB_REG_CT_RESET ||
            a == ABBE_MB_REG_CT_WORD_ORDER || a == ABBE_MB_REG_CT_DIR_SOURCE) {
            if (x > 1u) {
                return ABBE_MB_EX_ILLEGAL_VALUE;
            }
            if (a == ABBE_MB_REG_CT_ENABLE) {
                enable = x;
            } else if (a == ABBE_MB_REG_CT_RESET) {
                reset = x;
            } else if (a == ABBE_MB_REG_CT_WORD_ORDER) {
                word_order = x;
            } else {
                dir_source = x;
            }
        } else if (a == ABBE_MB_REG_CT_FADE_CYCLES) {
            cfg.fade_cycles = x;
        } else if (a == ABBE_MB_REG_CT_STALE_CYCLES) {
            cfg.stale_cycles = x;
        } else if (a >= ABBE_MB_REG_CT_WARN_X && a < ABBE_MB_REG_CT_SIGN_X) {
            unsigned k = (unsigned)(a - ABBE_MB_REG_CT_WARN_X);
            if ((k & 1u) == 0u) {
                int32_t val = to_i32(get32(r, &v[i]));
                unsigned j = (k / 2u) % ABBE_AXES;
                if (k < 6u) {
                    cfg.warn_nm[j] = val;
                } else if (k < 12u) {
                    cfg.limit_nm[j] = val;
                } else {
                    cfg.rate_nm_per_cycle[j] = val;
                }
            }
        } else {
            int16_t s = to_i16(x);
            if (s != 1 && s != -1) {
                return ABBE_MB_EX_ILLEGAL_VALUE;
            }
            cfg.axis_sign[a - ABBE_MB_REG_CT_SIGN_X] = (int8_t)s;
        }
    }

    if (limits) {
        /* The compensator must be off with zero output: re-initialising it
         * with the new limits then cannot make a correction jump. A reset in
         * the same request comes first: it clears a latched fault and
         * disables, so "reset, limits, enable" works from FAULT too. */
        int idle = (reset || !r->enabled) && (reset || r->out.state == ABBE_COMP_OFF);
        for (unsigned j = 0; j < ABBE_AXES; j++) {
            idle = idle && r->out.corr_nm[j] == 0;
        }
        if (!idle) {
            return ABBE_MB_EX_ILLEGAL_FUNCTION;
        }
        abbe_comp_t probe;
        if (abbe_comp_init(&probe, &cfg, NULL) != ABBE_OK) {
            return ABBE_MB_EX_ILLEGAL_VALUE;
        }
    }

    /* Everything checked: apply (reset, limits, enable, settings). */
    if (reset) {
        (void)abbe_comp_reset(&r->comp);
        r->enabled = 0;
    }
    if (limits) {
        const abbe_model_t *running = abbe_comp_model(&r->comp);
        r->stats_base = stats_sum(r);
        (void)abbe_comp_init(&r->comp, &cfg, running);
        if (r->pending >= 0) {
            (void)abbe_comp_swap_model(&r->comp, &r->slot[r->pending]);
        }
        r->comp_cfg = cfg;
    }
    if (enable == 1) {
        (void)abbe_comp_enable(&r->comp);
        r->enabled = 1;
    } else if (enable == 0) {
        (void)abbe_comp_disable(&r->comp);
        r->enabled = 0;
    }
    r->word_order = (uint8_t)word_order;
    r->dir_source = (uint8_t)dir_source;
    return 0;
}

/* ---- rendering blocks for reads -------------------------------------------------- */

static void render(const abbe_mb_regs_t *r, int b, uint16_t *d)
{
    const abbe_model_t *m = abbe_comp_model(&r->comp);
    switch (b) {
    case BLK_ID:
        d[0] = ABBE_MB_MAGIC_HI;
        d[1] = ABBE_MB_MAGIC_LO;
        d[2] = ABBE_MB_REGMAP_VERSION;
        d[3] = ABBE_VERSION_MAJOR;
        d[4] = ABBE_VERSION_MINOR;
        d[5] = ABBE_VERSION_PATCH;
        d[6] = ABBE_TABLE_FORMAT_MAJOR;
        d[7] = ABBE_TABLE_FORMAT_MINOR;
        put32(r, &d[8], ABBE_MB_SELFTEST_VALUE);
        put32(r, &d[10], model_crc_or_0(m));
        put32(r, &d[12], m != NULL ? abbe_model_size(m) : 0u);
        put32(r, &d[14], r->pending >= 0 ? abbe_model_crc(&r->slot[r->pending]) : 0u);
        put32(r, &d[16], (uint32_t)ABBE_MB_STAGING_MAX);
        d[18] = (uint16_t)(m != NULL ? abbe_model_features(m) : 0u);
        d[19] = r->max_clients;
        break;
    case BLK_ST: {
        abbe_comp_stats_t s = stats_sum(r);
        d[0] = (uint16_t)r->out.state;
        d[1] = (uint16_t)r->out.flags;
        d[2] = r->clients;
        d[3] = r->owner != 0u ? ABBE_MB_UPLOAD_OPEN : ABBE_MB_UPLOAD_IDLE;
        put32(r, &d[4], s.cycles);
        put32(r, &d[6], r->requests);
        put32(r, &d[8], r->exceptions);
        put32(r, &d[10], r->uploads_ok);
        put32(r, &d[12], r->uploads_rejected);
        put32(r, &d[14], s.invalid_inputs);
        put32(r, &d[16], s.stale_events);
        put32(r, &d[18], s.limit_trips);
        put32(r, &d[20], s.rate_limited);
        put32(r, &d[22], s.model_swaps);
        put32(r, &d[24], r->clients_refused);
        d[26] = r->last_exception;
        break;
    }
    case BLK_UP:
        d[0] = 0;
        d[1] = r->owner != 0u ? ABBE_MB_UPLOAD_OPEN : ABBE_MB_UPLOAD_IDLE;
        d[2] = r->session;
        d[3] = from_i16(r->result);
        put32(r, &d[4], r->filled);
        put32(r, &d[6], r->commit_len);
        put32(r, &d[8], r->commit_crc);
        put32(r, &d[10], r->rx_crc);
        put32(r, &d[12], r->model_crc);
        break;
    case BLK_IN:
        for (unsigned j = 0; j < ABBE_AXES; j++) {
            put32(r, &d[2u * j], from_i32(r->pos_nm[j]));
            d[6u + j] = from_i16(r->dir[j]);
            d[9u + j] = from_i16(r->temp_cdegc[j]);
        }
        d[12] = r->axis_fault;
        d[13] = r->cycle_in;
        break;
    case BLK_OUT:
        for (unsigned j = 0; j < ABBE_AXES; j++) {
            put32(r, &d[2u * j], from_i32(r->out.corr_nm[j]));
            put32(r, &d[6u + 2u * j], from_i32(r->err_nm[j]));
        }
        d[12] = (uint16_t)r->out.flags;
        d[13] = (uint16_t)r->out.state;
        d[14] = r->out_cycle;
        break;
    case BLK_TIN:
        for (unsigned k = 0; k < ABBE_MB_TH_INPUTS; k++) {
            d[k] = from_i16(r->th_in[k]);
        }
        d[17] = 0;
        put32(r, &d[18], r->th_dt_ms);
        d[20] = r->th_echo;
        break;
    case BLK_TOUT: {
        const abbe_thermal_state_t *th = r->th_bank >= 0 ? &r->th : NULL;
        int32_t y[ABBE_THERMAL_MAX_CHANNELS] = {0, 0, 0, 0, 0};
        unsigned n = th != NULL ? abbe_thermal_channels_q(th, y) : 0u;
        d[0] = (uint16_t)abbe_thermal_flags(th);
        d[1] = th != NULL ? (uint16_t)((abbe_thermal_n_inputs(&r->thermal[r->th_bank]) << 8) | n) : 0u;
        put32(r, &d[2], abbe_thermal_input_faults(th));
        put32(r, &d[4], abbe_thermal_events(th));
        for (unsigned c = 0; c < ABBE_THERMAL_MAX_CHANNELS; c++) {
            put32(r, &d[6u + 2u * c], from_i32(y[c]));
        }
        d[16] = r->th_samples;
        d[17] = r->th_echo;
        break;
    }
    default: /* BLK_CT */
        d[0] = r->enabled;
        d[1] = 0;
        d[2] = r->word_order;
        d[3] = r->dir_source;
        d[4] = r->comp_cfg.fade_cycles;
        d[5] = r->comp_cfg.stale_cycles;
        for (unsigned j = 0; j < ABBE_AXES; j++) {
            put32(r, &d[6u + 2u * j], from_i32(r->comp_cfg.warn_nm[j]));
            put32(r, &d[12u + 2u * j], from_i32(r->comp_cfg.limit_nm[j]));
            put32(r, &d[18u + 2u * j], from_i32(r->comp_cfg.rate_nm_per_cycle[j]));
            d[24u + j] = from_i16(r->comp_cfg.axis_sign[j]);
        }
        break;
    }
}

/* ---- public API ------------------------------------------------------------------------ */

void abbe_mb_regs_default_config(abbe_mb_regs_config_t *cfg)
{
    if (cfg == NULL) {
        return;
    }
    memset(cfg, 0, sizeof *cfg);
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        cfg->comp.warn_nm[j] = 100000;
        cfg->comp.limit_nm[j] = 500000;
        cfg->comp.rate_nm_per_cycle[j] = 1000;
        cfg->comp.axis_sign[j] = 1;
    }
    cfg->comp.fade_cycles = 1000;
    cfg->comp.stale_cycles = 10;
    cfg->word_order = ABBE_MB_WORD_ORDER_HIGH_FIRST;
    cfg->dir_source = 0;
    cfg->max_clients = 1;
    cfg->upload_timeout_ms = 10000;
    cfg->cycle_us = 1000;
}

abbe_status_t abbe_mb_regs_init(abbe_mb_regs_t *r, const abbe_mb_regs_config_t *cfg,
                                const void *blob, size_t size)
{
    if (r == NULL || cfg == NULL || cfg->word_order > 1u || cfg->dir_source > 1u ||
        size > (size_t)ABBE_MB_STAGING_MAX || (blob == NULL && size != 0u)) {
        return ABBE_E_ARG;
    }
    abbe_comp_t probe;
    if (abbe_comp_init(&probe, &cfg->comp, NULL) != ABBE_OK) {
        return ABBE_E_ARG;
    }
    memset(r, 0, sizeof *r);
    r->comp_cfg = cfg->comp;
    r->word_order = cfg->word_order;
    r->dir_source = cfg->dir_source;
    r->max_clients = cfg->max_clients;
    r->upload_timeout_ms = cfg->upload_timeout_ms;
    r->running = r->pending = r->staging = -1;
    r->th_bank = -1;
    r->cycle_us = cfg->cycle_us != 0u ? cfg->cycle_us : 1000u;
    r->th_dt_ms = 1000u;
    for (unsigned k = 0; k < ABBE_MB_TH_INPUTS; k++) {
        r->th_in[k] = ABBE_MB_TEMP_NO_READING;
    }
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        r->temp_cdegc[j] = 2000; /* 20 degC, the ISO 1 reference, until the controller writes */
    }
    (void)abbe_comp_init(&r->comp, &r->comp_cfg, NULL);
    r->out.state = ABBE_COMP_OFF;
    if (blob == NULL) {
        return ABBE_OK;
    }
    memcpy(r->bank[0], blob, size);
    abbe_status_t st = abbe_thermal_load(&r->slot[0], &r->thermal[0], r->bank[0], size);
    if (st != ABBE_OK) {
        memset(r->bank[0], 0, sizeof r->bank[0]);
        return st;
    }
    (void)abbe_comp_init(&r->comp, &r->comp_cfg, &r->slot[0]);
    r->running = 0;
    r->model_crc = abbe_model_crc(&r->slot[0]);
    return ABBE_OK;
}

int abbe_mb_regs_check_read(const abbe_mb_regs_t *r, uint32_t conn, uint16_t addr, uint16_t count)
{
    if (r == NULL) {
        return ABBE_MB_EX_DEVICE_FAILURE;
    }
    if (count < 1u || count > MAX_READ) {
        return ABBE_MB_EX_ILLEGAL_VALUE;
    }
    int b = find_block(addr, count);
    if (b == BLK_NONE) {
        return ABBE_MB_EX_ILLEGAL_ADDRESS;
    }
    if (b == BLK_STAGING) {
        return session_check(r, conn);
    }
    return 0;
}

int abbe_mb_regs_read(abbe_mb_regs_t *r, uint32_t conn, uint16_t addr, uint16_t count,
                      uint16_t *dst)
{
    int ex = abbe_mb_regs_check_read(r, conn, addr, count);
    if (ex != 0 || dst == NULL) {
        return ex != 0 ? ex : ABBE_MB_EX_DEVICE_FAILURE;
    }
    int b = find_block(addr, count);
    if (b == BLK_STAGING) {
        const uint8_t *p = &r->bank[r->staging][2u * (uint32_t)(addr - ABBE_MB_REG_STAGING)];
        for (uint16_t i = 0; i < count; i++) {
            dst[i] = (uint16_t)(((unsigned)p[2u * i] << 8) | p[2u * i + 1u]);
        }
        r->last_activity_ms = r->now_ms;
        return 0;
    }
    uint16_t buf[BLOCK_MAX];
    memset(buf, 0, sizeof buf);
    render(r, b, buf);
    memcpy(dst, &buf[addr - blocks[b].base], (size_t)count * sizeof *dst);
    return 0;
}

int abbe_mb_regs_write(abbe_mb_regs_t *r, uint32_t conn, uint16_t addr, uint16_t count,
                       const uint8_t *values_be)
{
    if (r == NULL || values_be == NULL) {
        return ABBE_MB_EX_DEVICE_FAILURE;
    }
    if (count < 1u || count > MAX_WRITE) {
        return ABBE_MB_EX_ILLEGAL_VALUE;
    }
    int b = find_block(addr, count);
    if (b == BLK_STAGING) {
        return write_staging(r, conn, addr, count, values_be);
    }
    if (b != BLK_UP && b != BLK_IN && b != BLK_CT && b != BLK_TIN) {
        return ABBE_MB_EX_ILLEGAL_ADDRESS; /* unmapped or read only */
    }
    if (pair_second(addr) || pair_second((uint16_t)(addr + count))) {
        return ABBE_MB_EX_ILLEGAL_ADDRESS; /* half of a 32-bit value */
    }
    uint16_t v[MAX_WRITE];
    for (uint16_t i = 0; i < count; i++) {
        v[i] = (uint16_t)(((unsigned)values_be[2u * i] << 8) | values_be[2u * i + 1u]);
    }
    if (b == BLK_UP) {
        if (r->owner == conn) {
            r->last_activity_ms = r->now_ms;
        }
        return write_upload(r, conn, addr, count, v);
    }
    if (b == BLK_IN) {
        return write_inputs(r, addr, count, v);
    }
    if (b == BLK_TIN) {
        return write_thermal(r, addr, count, v);
    }
    return write_control(r, addr, count, v);
}

void abbe_mb_regs_disconnect(abbe_mb_regs_t *r, uint32_t conn)
{
    if (r != NULL && conn != 0u && r->owner == conn) {
        session_close(r, ABBE_MB_UP_DISCONNECTED);
    }
}

void abbe_mb_regs_tick(abbe_mb_regs_t *r, uint32_t now_ms)
{
    if (r == NULL) {
        return;
    }
    r->now_ms = now_ms;
    if (r->owner != 0u && r->upload_timeout_ms != 0u &&
        (uint32_t)(now_ms - r->last_activity_ms) >= r->upload_timeout_ms) {
        session_close(r, ABBE_MB_UP_TIMEOUT);
    }
}

void abbe_mb_regs_count_request(abbe_mb_regs_t *r, uint8_t function, int exception)
{
    if (r == NULL) {
        return;
    }
    if (exception == 0) {
        r->requests++;
    } else {
        r->exceptions++;
        r->last_exception = (uint16_t)(((unsigned)function << 8) | ((unsigned)exception & 0xFFu));
    }
}

void abbe_mb_regs_set_clients(abbe_mb_regs_t *r, uint16_t open, uint32_t refused)
{
    if (r != NULL) {
        r->clients = open;
        r->clients_refused = refused;
    }
}

void abbe_mb_regs_set_event_hook(abbe_mb_regs_t *r, abbe_mb_event_fn fn, void *ctx)
{
    if (r != NULL) {
        r->event_fn = fn;
        r->event_ctx = ctx;
    }
}

const abbe_comp_t *abbe_mb_regs_comp(const abbe_mb_regs_t *r)
{
    return r != NULL ? &r->comp : NULL;
}
