/* abbe Modbus port: the register map engine (transport independent).
 *
 * abbe_mb_regs_t owns a compensator, the table banks and the upload session,
 * and answers register reads and writes as docs/modbus-registers.md specifies.
 * It knows nothing of sockets, serial lines or libmodbus: abbe-modbusd wraps it
 * with libmodbus (abbe/modbus_server.h), a drive with its own Modbus stack can
 * call it directly from its register callbacks. No heap, no I/O, no globals:
 * all state is in the caller-owned struct (about 3 x ABBE_MB_STAGING_MAX bytes,
 * so give it static storage).
 *
 * Request functions return 0, or the Modbus exception code (ABBE_MB_EX_*) to
 * answer with, in which case nothing was changed. A connection token (conn,
 * any non-zero value unique to one client connection) identifies who owns an
 * upload session.
 */
#ifndef ABBE_MODBUS_PORT_H
#define ABBE_MODBUS_PORT_H

#include <stddef.h>
#include <stdint.h>

#include "abbe/abbe.h"
#include "abbe/modbus_regs.h"

/* Staging area, and each of the three table banks: bytes. The largest table
 * format 1.1 allows (3 axes x 40 rows x 6 terms, plus 3 reversal blocks of 8
 * rows) is 6212 bytes (format 1.0: 6020). */
#ifndef ABBE_MB_STAGING_MAX
#define ABBE_MB_STAGING_MAX 16384
#endif
#if ABBE_MB_STAGING_MAX < 260 || ABBE_MB_STAGING_MAX > 32768 || (ABBE_MB_STAGING_MAX % 4) != 0
#error "ABBE_MB_STAGING_MAX must be a multiple of 4 in [260, 32768]"
#endif

#define ABBE_MB_BANKS 3 /* running, queued, staging */

/* What happened to an upload session or a table, reported to an event hook
 * (abbe_mb_regs_set_event_hook) as it happens, e.g. for a log. */
typedef enum {
    ABBE_MB_EV_UPLOAD_BEGIN = 1, /* conn opened session (UP_SESSION) */
    ABBE_MB_EV_UPLOAD_END = 2,   /* session of conn closed with result (its UP_RESULT); OK: size, crc */
    ABBE_MB_EV_UPLOAD_BUSY = 3,  /* a BEGIN from conn refused: session of owner is open */
    ABBE_MB_EV_MODEL_SWAP = 4    /* the queued table (crc, size) took effect in the cycle IN_CYCLE = cycle */
} abbe_mb_event_kind_t;

typedef struct {
    abbe_mb_event_kind_t kind;
    uint32_t conn;     /* the connection concerned (the session's owner for BEGIN/END) */
    uint32_t owner;    /* BUSY: the connection owning the open session */
    uint16_t session;  /* BEGIN, END, BUSY */
    int16_t result;    /* END: ABBE_MB_UP_* or a negative abbe_status_t */
    uint16_t cycle;    /* MODEL_SWAP: IN_CYCLE of that cycle */
    uint32_t size;     /* END OK, MODEL_SWAP: table bytes */
    uint32_t crc;      /* END OK, MODEL_SWAP: table CRC-32 */
} abbe_mb_event_t;

typedef void (*abbe_mb_event_fn)(void *ctx, const abbe_mb_event_t *ev);

typedef struct {
    abbe_comp_config_t comp;     /* initial limits (the CT_* registers change them) */
    uint8_t word_order;          /* ABBE_MB_WORD_ORDER_* */
    uint8_t dir_source;          /* 0 IN_DIR registers, 1 sign of the position change */
    uint16_t max_clients;        /* reported in ID_MAX_CLIENTS */
    uint32_t upload_timeout_ms;  /* idle upload sessions are dropped after this; 0 = never */
    uint32_t cycle_us;           /* the controller's IN_CYCLE period, us: the thermal runtime's clock (default 1000) */
} abbe_mb_regs_config_t;

/* Register map state. Allocate it yourself (static); all fields are private. */
typedef struct {
    abbe_comp_t comp;
    abbe_comp_config_t comp_cfg;
    abbe_comp_stats_t stats_base;       /* counters of compensators replaced by a limit change */
    abbe_model_t slot[ABBE_MB_BANKS];
    abbe_thermal_model_t thermal[ABBE_MB_BANKS]; /* each bank's thermal block (n_channels 0: none) */
    abbe_thermal_state_t th;            /* the running table's thermal state */
    int8_t th_bank;                     /* bank th was started for, -1 none */
    uint32_t cycle_us;
    int16_t th_in[ABBE_MB_TH_INPUTS];   /* IN_TH_* as written */
    uint32_t th_dt_ms;
    uint16_t th_samples, th_echo;
    uint8_t bank[ABBE_MB_BANKS][ABBE_MB_STAGING_MAX];
    int8_t running;                     /* bank index in use, -1 none */
    int8_t pending;                     /* bank queued for the next cycle, -1 none */
    int8_t staging;                     /* bank of the open upload, -1 none */
    uint8_t enabled;
    uint8_t word_order;
    uint8_t dir_source;
    uint8_t pos_written;                /* bit j: IN_POS_j written since the last cycle */
    uint8_t have_last_pos;
    /* upload session */
    uint32_t owner;                     /* connection token, 0 = no open session */
    uint32_t filled;
    uint32_t last_activity_ms;
    uint32_t upload_timeout_ms;
    uint32_t commit_len, commit_crc, rx_crc, model_crc;
    uint16_t session;
    int16_t result;
    /* inputs */
    int32_t pos_nm[ABBE_AXES];
    int32_t last_pos_nm[ABBE_AXES];
    int16_t dir[ABBE_AXES];
    int16_t temp_cdegc[ABBE_AXES];
    uint16_t axis_fault;
    uint16_t cycle_in;
    /* outputs */
    abbe_comp_output_t out;
    int32_t err_nm[ABBE_AXES];
    uint16_t out_cycle;
    /* counters */
    uint32_t requests, exceptions, uploads_ok, uploads_rejected, clients_refused;
    uint16_t clients, max_clients, last_exception;
    uint32_t now_ms;
    /* event hook (NULL: none) */
    abbe_mb_event_fn event_fn;
    void *event_ctx;
} abbe_mb_regs_t;

/* Defaults: word order high first, direction from the IN_DIR registers, warn
 * 100 um, limit 500 um, rate 1 um/cycle, fade 1000 cycles, stale 10 cycles,
 * axis signs +1, 1 client, upload timeout 10 s. */
void abbe_mb_regs_default_config(abbe_mb_regs_config_t *cfg);

/* Start with the compensator disabled. blob (may be NULL, size 0) is an initial
 * table: copied into a bank and in use from the first cycle.
 * Returns ABBE_OK; ABBE_E_ARG for NULL r/cfg, an invalid config or a blob larger
 * than ABBE_MB_STAGING_MAX; or the table's validation status (r is then
 * initialised without a model). */
abbe_status_t abbe_mb_regs_init(abbe_mb_regs_t *r, const abbe_mb_regs_config_t *cfg,
                                const void *blob, size_t size);

/* Read count (1..125) registers from addr into dst (host order).
 * Returns 0 or ABBE_MB_EX_ILLEGAL_VALUE (count), _ILLEGAL_ADDRESS (not all
 * inside one mapped block), _ILLEGAL_FUNCTION / _BUSY (staging without /
 * of another's upload session). */
int abbe_mb_regs_read(abbe_mb_regs_t *r, uint32_t conn, uint16_t addr, uint16_t count,
                      uint16_t *dst);

/* The checks of abbe_mb_regs_read without reading (for FC23, before its write). */
int abbe_mb_regs_check_read(const abbe_mb_regs_t *r, uint32_t conn, uint16_t addr,
                            uint16_t count);

/* Write count (1..123) registers at addr; values_be holds 2 * count bytes as on
 * the wire (big-endian registers). The write is checked as a whole before any
 * of it takes effect; a write that covers IN_CYCLE then runs one cycle.
 * Returns 0 or an ABBE_MB_EX_* code (the map is then unchanged, except for a
 * refused commit: its session closes and UP_RESULT says why). */
int abbe_mb_regs_write(abbe_mb_regs_t *r, uint32_t conn, uint16_t addr, uint16_t count,
                       const uint8_t *values_be);

/* A connection closed: drops its upload session (UP_RESULT DISCONNECTED). */
void abbe_mb_regs_disconnect(abbe_mb_regs_t *r, uint32_t conn);

/* Advance the clock (ms, wrapping) and drop an upload idle for the timeout. */
void abbe_mb_regs_tick(abbe_mb_regs_t *r, uint32_t now_ms);

/* Accounting by the transport: one answered request (exception 0 = normal
 * reply, else the code it got, function = its function code), and the number
 * of open / refused connections. */
void abbe_mb_regs_count_request(abbe_mb_regs_t *r, uint8_t function, int exception);
void abbe_mb_regs_set_clients(abbe_mb_regs_t *r, uint16_t open, uint32_t refused);

/* Call fn(ctx, event) for every upload session begun, ended or refused as
 * busy and every table taken into use, synchronously from the call that
 * caused it (fn must not call back into r). NULL fn: no hook. Set it after
 * abbe_mb_regs_init (which clears it). */
void abbe_mb_regs_set_event_hook(abbe_mb_regs_t *r, abbe_mb_event_fn fn, void *ctx);

/* The compensator (read only: for status displays and tests). */
const abbe_comp_t *abbe_mb_regs_comp(const abbe_mb_regs_t *r);

#endif /* ABBE_MODBUS_PORT_H */
