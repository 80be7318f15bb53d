/* abbe CAN port: the compensator on a CANopen bus of CiA 402 servo drives.
 *
 * This header is the portable part (C99, no OS, no heap, no stdio): CAN frame
 * type, configuration, and the node that turns received frames into frames to
 * send. It knows nothing of sockets or files:
 *   abbe_can_driver.h  the driver contract (send/receive one frame) + stub target
 *   abbe_can_config.h  the configuration file parser (host)
 *   abbe_can_log.h     candump -l log lines (replay)
 *   abbe_can_linux.h   file-descriptor driver, SocketCAN socket, model files (Linux)
 *
 * The cycle (docs/can.md): drives send their position actual value (0x6064) in
 * a TPDO; on each SYNC the node takes the latest position of every axis (and,
 * when configured, the latest axis temperatures from the temperature frame),
 * runs abbe_comp_step_q() and answers with each drive's position offset
 * (0x60B0) in an RPDO, plus an optional status frame (and, periodically, an
 * info frame).
 * All state is in the caller-owned abbe_can_node_t.
 */
#ifndef ABBE_CAN_H
#define ABBE_CAN_H

#include <stddef.h>
#include <stdint.h>

#include "abbe/abbe.h"

/* ---- status codes ------------------------------------------------------ */

/* Port status codes. 0 is success; the port's failures are below -100 so they
 * never collide with the core's abbe_status_t (ABBE_STATUS_MIN .. -1, today
 * -18 .. -1; -99 .. -1 is the core's range), which port functions pass through
 * unchanged (a model that fails validation returns the core's code, e.g.
 * ABBE_E_CRC). */
typedef enum {
    ABBE_CAN_OK = 0,
    ABBE_CAN_E_ARG = -101,         /* NULL pointer or argument outside its range */
    ABBE_CAN_E_CONFIG = -102,      /* configuration invalid (see the field and message) */
    ABBE_CAN_E_AGAIN = -103,       /* nothing to receive now / transmit queue full */
    ABBE_CAN_E_CLOSED = -104,      /* the peer closed the connection */
    ABBE_CAN_E_IO = -105,          /* an operating-system I/O call failed (errno) */
    ABBE_CAN_E_BUSY = -106,        /* a model is already queued: retry after the next SYNC */
    ABBE_CAN_E_TOO_BIG = -107,     /* model file larger than ABBE_CAN_BLOB_MAX */
    ABBE_CAN_E_UNSUPPORTED = -108, /* not available here (no SocketCAN, CAN FD log line) */
    ABBE_CAN_E_FRAME = -109,       /* a received record is not one struct can_frame */
    ABBE_CAN_E_PARSE = -110        /* a log line is not in candump -l format */
} abbe_can_status_t;

/* Human-readable, static, never NULL; core codes are described by abbe_strerror(). */
const char *abbe_can_strerror(int status);
/* The code's name ("ABBE_E_CRC", "ABBE_CAN_E_BUSY"), static, never NULL. */
const char *abbe_can_status_name(int status);

/* ---- frames -------------------------------------------------------------- */

/* Identifier flags: the bit layout of SocketCAN's can_id (linux/can.h). */
#define ABBE_CAN_EFF_FLAG 0x80000000u /* 29-bit identifier */
#define ABBE_CAN_RTR_FLAG 0x40000000u /* remote transmission request */
#define ABBE_CAN_ERR_FLAG 0x20000000u /* error frame from the controller */
#define ABBE_CAN_SFF_MASK 0x000007FFu
#define ABBE_CAN_EFF_MASK 0x1FFFFFFFu
#define ABBE_CAN_MAX_DLEN 8u

/* One classic CAN frame. */
typedef struct {
    uint32_t id;                         /* identifier plus ABBE_CAN_*_FLAG bits */
    uint8_t dlc;                         /* payload length; a received value > 8 is a wrong DLC */
    uint8_t data[ABBE_CAN_MAX_DLEN];
} abbe_can_frame_t;

/* Little-endian field helpers (CANopen is little-endian). */
void abbe_can_put_i32(uint8_t *p, int32_t v);
int32_t abbe_can_get_i32(const uint8_t *p);
void abbe_can_put_u16(uint8_t *p, uint16_t v);
uint16_t abbe_can_get_u16(const uint8_t *p);
void abbe_can_put_u32(uint8_t *p, uint32_t v);
uint32_t abbe_can_get_u32(const uint8_t *p);

/* ---- configuration ------------------------------------------------------- */

#define ABBE_CAN_IFNAME_MAX 16u   /* IFNAMSIZ */
#define ABBE_CAN_PATH_MAX 512u
#define ABBE_CAN_NO_BYTE (-1)     /* statusword_byte: the TPDO carries no statusword */

/* CiA 301 predefined connection set. */
#define ABBE_CAN_SYNC_COB_ID 0x080u
#define ABBE_CAN_TPDO1_BASE 0x180u
#define ABBE_CAN_RPDO1_BASE 0x200u
#define ABBE_CAN_TPDO2_BASE 0x280u
#define ABBE_CAN_RPDO2_BASE 0x300u
#define ABBE_CAN_DEFAULT_NODE_ID 0x70u /* the compensator's own node id */

/* Temperature frame (docs/can.md): DLC 6, three INT16 axis temperatures X, Y,
 * Z in 0.01 degC, little-endian. ABBE_CAN_TEMP_NO_READING for an axis means
 * "no reading in this frame": the axis keeps the temperature it has. Any
 * other value outside [ABBE_CAN_TEMP_MIN_CDEGC, ABBE_CAN_TEMP_MAX_CDEGC]
 * (-50 .. +150 degC: a sensor fault, not a machine temperature) makes the
 * whole frame a bad value: counted and ignored. */
#define ABBE_CAN_TEMP_DLC 6u
#define ABBE_CAN_TEMP_NO_READING (-32768)
#define ABBE_CAN_TEMP_MIN_CDEGC (-5000)
#define ABBE_CAN_TEMP_MAX_CDEGC 15000

/* Thermal frames (docs/can.md, format 1.3 tables with a thermal block): DLC 8,
 * frame g at thermal_cob_id + g carries inputs 4g .. 4g+3 of the model as
 * INT16 LE: temperatures in 0.01 degC, the spindle speed in rpm;
 * ABBE_CAN_TEMP_NO_READING = no reading (the runtime's open-circuit fault).
 * The frame that carries the model's last input completes a sample. */
#define ABBE_CAN_THERMAL_DLC 8u
#define ABBE_CAN_THERMAL_FRAMES 5u  /* 17 inputs, 4 per frame */
#define ABBE_CAN_THERMAL_PER_FRAME 4u

/* CiA 402 statusword bit 3: Fault. A drive reporting it is an axis fault. */
#define ABBE_CAN_STATUSWORD_FAULT 0x0008u

/* Command frame byte 0 (docs/can.md). */
#define ABBE_CAN_CMD_ENABLE 0x01u
#define ABBE_CAN_CMD_DISABLE 0x02u
#define ABBE_CAN_CMD_RESET 0x03u   /* clear a latched limit fault and disable */
#define ABBE_CAN_CMD_RELOAD 0x04u  /* load the model file again (like SIGHUP) */

/* One axis: its drive, scaling, frame layouts and compensator limits.
 * A COB-ID of 0 means "derive from node_id" (0x180 + id, 0x200 + id). */
typedef struct {
    uint8_t node_id;            /* drive's CANopen node id, 1..127 (required) */
    double increments_per_mm;   /* drive position increments per mm, > 0 (required) */
    int8_t sign;                /* +1: increments count along the machine axis, -1: against it */
    int32_t origin_nm;          /* machine coordinate at drive position 0, nm */
    int8_t correction_sign;     /* compensator axis sign (abbe_comp_config_t.axis_sign) */
    int32_t warn_nm;            /* warning limit on |correction|, nm, > 0 */
    int32_t limit_nm;           /* error limit on |correction|, nm, >= warn_nm */
    int32_t rate_nm_per_cycle;  /* max correction change per SYNC cycle, nm, > 0 */
    int32_t deadband_nm;        /* direction detection deadband, nm, >= 0 */
    int32_t temp_mdegc;         /* axis temperature handed to the model until the temperature
                                   frame gives one (or always, without that frame), m°C */
    uint32_t tpdo_cob_id;       /* drive -> compensator: position actual value 0x6064 */
    uint8_t tpdo_dlc;           /* exact DLC of that TPDO, 4..8 */
    uint8_t position_byte;      /* INT32 position at data[position_byte .. +4) */
    int8_t statusword_byte;     /* UINT16 statusword 0x6041 at that byte, or ABBE_CAN_NO_BYTE */
    uint32_t rpdo_cob_id;       /* compensator -> drive: position offset 0x60B0 */
    uint8_t rpdo_dlc;           /* DLC sent, 4..8 (unused bytes are 0) */
    uint8_t offset_byte;        /* INT32 offset at data[offset_byte .. +4) */
} abbe_can_axis_config_t;

typedef struct {
    char interface[ABBE_CAN_IFNAME_MAX];  /* SocketCAN interface, e.g. "can0" */
    char model_path[ABBE_CAN_PATH_MAX];   /* model blob (docs/table-format.md) */
    uint8_t node_id;                      /* compensator's node id: default status/info/command ids */
    uint32_t sync_cob_id;                 /* SYNC (DLC 0, or 1 with a counter) */
    uint8_t status_enable;                /* send a status frame every cycle */
    uint32_t status_cob_id;               /* 0: 0x180 + node_id */
    uint16_t info_period_cycles;          /* info frame every N cycles; 0: never */
    uint32_t info_cob_id;                 /* 0: 0x280 + node_id */
    uint8_t command_enable;               /* accept command frames */
    uint32_t command_cob_id;              /* 0: 0x200 + node_id */
    uint16_t fade_cycles;                 /* compensator fade length, >= 1 */
    uint16_t stale_cycles;                /* SYNC cycles without a position before fading out, >= 1 */
    uint8_t enable_on_start;              /* enable the compensator at start */
    uint8_t temp_enable;                  /* read axis temperatures from the temperature frame */
    uint32_t temp_cob_id;                 /* 0: 0x300 + node_id (the compensator's RPDO2) */
    uint16_t temp_stale_cycles;           /* cycles without a reading before TEMP_STALE; 0: never */
    uint8_t thermal_enable;               /* thermal frames for the table's thermal block (format 1.3) */
    uint32_t thermal_cob_id;              /* first of the 5 thermal frames' COB-IDs (default 0x3F0) */
    uint32_t cycle_us;                    /* SYNC period, us (the thermal runtime's time base), 100..1000000 */
    abbe_can_axis_config_t axis[ABBE_AXES];
} abbe_can_config_t;

/* Fill *cfg with the defaults documented in docs/can.md. The axes' node_id and
 * increments_per_mm stay 0 (required), model_path empty. */
void abbe_can_config_defaults(abbe_can_config_t *cfg);

/* Resolve derived COB-IDs (0 -> from the node id) and check every value and
 * the frame map (no COB-ID used twice except TPDOs/RPDOs deliberately shared
 * by axes with compatible layouts). On failure returns ABBE_CAN_E_CONFIG and
 * sets *field (e.g. "axis.Y.rpdo_cob_id", the name used in the configuration
 * file) and *why to static strings. field/why may be NULL. */
int abbe_can_config_check(abbe_can_config_t *cfg, const char **field, const char **why);

/* Drive increments <-> machine nanometres (docs/can.md "Scaling"):
 *   pos_nm = origin_nm + round(sign * incr * 1e6 / increments_per_mm)
 *   incr   = round(corr_nm * increments_per_mm / 1e6) * sign
 * rounding half away from zero, saturated to int32. */
int32_t abbe_can_incr_to_nm(const abbe_can_axis_config_t *ax, int32_t incr);
int32_t abbe_can_nm_to_incr(const abbe_can_axis_config_t *ax, int32_t corr_nm);

/* ---- node ----------------------------------------------------------------- */

/* Largest model blob the node holds (a full format-1.0 table is < 6 KiB). */
#define ABBE_CAN_BLOB_MAX 16384u
/* Most frames one received frame can produce: 3 offsets, info, status. */
#define ABBE_CAN_MAX_TX 5u
/* Ages at or above this are reported as 255 in the status frame. */
#define ABBE_CAN_AGE_MAX 255u

/* What a received frame was. Every kind but SYNC, POSITION, COMMAND and
 * TEMPERATURE is counted and otherwise ignored. */
typedef enum {
    ABBE_CAN_RX_SYNC = 0,      /* a cycle ran; frames to send were produced */
    ABBE_CAN_RX_POSITION = 1,  /* a drive's position TPDO */
    ABBE_CAN_RX_COMMAND = 2,   /* a command frame */
    ABBE_CAN_RX_BAD_DLC = 3,   /* known id, wrong DLC */
    ABBE_CAN_RX_UNKNOWN = 4,   /* id not in the frame map (includes 29-bit ids) */
    ABBE_CAN_RX_RTR = 5,       /* remote request */
    ABBE_CAN_RX_ERROR = 6,     /* error frame */
    ABBE_CAN_RX_BAD_COMMAND = 7, /* command frame with an unknown command byte */
    ABBE_CAN_RX_TEMPERATURE = 8, /* the temperature frame */
    ABBE_CAN_RX_BAD_VALUE = 9,   /* temperature frame with a value out of range */
    ABBE_CAN_RX_THERMAL = 10     /* a thermal frame (docs/can.md) */
} abbe_can_rx_kind_t;

typedef struct {
    uint32_t frames_rx;       /* frames handed to abbe_can_node_rx */
    uint32_t syncs;           /* cycles run */
    uint32_t positions;       /* position TPDOs taken */
    uint32_t commands;        /* commands executed */
    uint32_t bad_dlc;
    uint32_t unknown_id;
    uint32_t rtr;
    uint32_t error_frames;
    uint32_t bad_command;
    uint32_t bad_value;       /* temperature frames with a value out of range */
    uint32_t malformed;       /* records that were not one CAN frame (driver level) */
    uint32_t temperatures;    /* temperature frames taken */
    uint32_t thermal_frames;  /* thermal frames taken */
    uint32_t thermal_samples; /* thermal samples handed to the runtime */
    uint32_t frames_tx;       /* frames produced */
    uint32_t tx_errors;       /* frames the driver could not send */
    uint32_t stale_cycles;    /* cycles in which some axis had no fresh position */
    uint32_t model_loads_ok;
    uint32_t model_loads_failed;
} abbe_can_counters_t;

/* Per-axis receive state. Private. */
typedef struct {
    int32_t pos_incr;
    uint16_t statusword;
    uint8_t have_pos;
    uint8_t fresh;
    uint32_t age_cycles;
    int32_t anchor_nm;
    int8_t dir;
    uint8_t anchor_valid;
} abbe_can_axis_state_t;

/* The node. Allocate it yourself (it holds two model blobs, about 33 KiB);
 * all fields are private. */
typedef struct {
    abbe_can_config_t cfg;
    abbe_comp_t comp;
    abbe_model_t model[2];
    uint8_t blob[2][ABBE_CAN_BLOB_MAX];
    int8_t pending_slot;      /* slot queued in comp, -1 if none */
    abbe_can_axis_state_t ax[ABBE_AXES];
    abbe_can_counters_t count;
    abbe_comp_output_t out;
    uint8_t fresh_mask;
    uint8_t seq;
    uint8_t reload_requested;
    uint8_t info_due;
    uint16_t info_countdown;
    int last_load_status;
    /* temperatures (from cfg axis temp_mdegc until the temperature frame gives them) */
    int32_t temp_mdegc[ABBE_AXES];
    uint32_t temp_age[ABBE_AXES];    /* cycles since the axis' last reading */
    uint32_t temp_frame_age;         /* cycles since the last temperature frame taken */
    uint8_t temp_reading;            /* bit j: axis j has had a reading */
    uint8_t temp_fresh;              /* bit j: a reading for axis j since the last SYNC; bit 3: a frame */
    uint8_t temp_frame_seen;         /* a temperature frame was ever taken */
    uint8_t temp_stale;              /* TEMP_STALE of the last cycle */
    /* the thermal block (format 1.3): per slot, the running one's state */
    abbe_thermal_model_t thermal[2];
    abbe_thermal_state_t th_state;
    int8_t th_slot;                  /* slot th_state was started for, -1: none */
    int32_t th_x[ABBE_THERMAL_MAX_INPUTS]; /* this sample's readings, m degC / rpm */
    uint32_t th_valid;               /* bit k: input k has a reading in this sample */
    uint32_t th_cycles;              /* SYNC cycles since the last sample */
    uint8_t th_sampled;              /* a sample was taken */
} abbe_can_node_t;

/* Check *cfg (abbe_can_config_check) and start the node without a model; the
 * compensator is enabled if cfg->enable_on_start. Returns ABBE_CAN_OK,
 * ABBE_CAN_E_ARG (NULL) or ABBE_CAN_E_CONFIG (node untouched). */
int abbe_can_node_init(abbe_can_node_t *node, const abbe_can_config_t *cfg);

/* The node's resolved configuration. */
const abbe_can_config_t *abbe_can_node_config(const abbe_can_node_t *node);

/* Handle one received frame. On SYNC, writes the frames to send to
 * tx[0 .. *n_tx) (at most ABBE_CAN_MAX_TX): the RPDOs (one per distinct RPDO
 * COB-ID, in axis order), the info frame when due, and the status frame last
 * (so a listener knows the cycle's frames are complete).
 * Otherwise *n_tx = 0. Never fails for any frame content: returns the kind
 * (abbe_can_rx_kind_t, >= 0), or ABBE_CAN_E_ARG for NULL pointers. */
int abbe_can_node_rx(abbe_can_node_t *node, const abbe_can_frame_t *rx,
                     abbe_can_frame_t tx[ABBE_CAN_MAX_TX], size_t *n_tx);

/* Count a received record that was not one CAN frame (wrong record size). */
void abbe_can_node_count_malformed(abbe_can_node_t *node);
/* Count a frame the driver failed to send. */
void abbe_can_node_count_tx_error(abbe_can_node_t *node);

/* Model swap. The node keeps two blob slots: the running model's and a spare.
 * abbe_can_node_model_buffer() returns the spare (capacity ABBE_CAN_BLOB_MAX)
 * to fill in place, or NULL while a model is already queued (it takes effect
 * at the next SYNC; then the old slot becomes the spare).
 * abbe_can_node_commit_model() validates the first size bytes of the spare
 * and queues them for the next SYNC. On failure it returns the core's status
 * (ABBE_E_CRC, ...) and the running model goes on untouched.
 * abbe_can_node_load_model() copies blob into the spare and commits it.
 * All three count the attempt and make the next cycle send an info frame. */
uint8_t *abbe_can_node_model_buffer(abbe_can_node_t *node, size_t *capacity);
int abbe_can_node_commit_model(abbe_can_node_t *node, size_t size);
int abbe_can_node_load_model(abbe_can_node_t *node, const void *blob, size_t size);
/* Record a failed load that never reached validation (file unreadable: ABBE_CAN_E_IO). */
void abbe_can_node_note_load_failure(abbe_can_node_t *node, int status);
/* 1 if a model is queued for the next SYNC. */
int abbe_can_node_model_pending(const abbe_can_node_t *node);

/* 1 once after a RELOAD command was received (the caller loads the file). */
int abbe_can_node_take_reload_request(abbe_can_node_t *node);
/* Ask for a reload (e.g. from SIGHUP): abbe_can_node_take_reload_request() reports it. */
void abbe_can_node_request_reload(abbe_can_node_t *node);

/* Compensator control, as the command frames do. */
int abbe_can_node_enable(abbe_can_node_t *node);
int abbe_can_node_disable(abbe_can_node_t *node);
int abbe_can_node_reset(abbe_can_node_t *node);

/* Observers. */
abbe_can_counters_t abbe_can_node_counters(const abbe_can_node_t *node);
uint32_t abbe_can_node_ignored(const abbe_can_node_t *node); /* all ignored frames and records */
const abbe_comp_output_t *abbe_can_node_output(const abbe_can_node_t *node); /* last cycle */
abbe_comp_stats_t abbe_can_node_comp_stats(const abbe_can_node_t *node);
uint32_t abbe_can_node_age(const abbe_can_node_t *node, unsigned axis); /* cycles since its last position */
uint32_t abbe_can_node_model_crc(const abbe_can_node_t *node);      /* running model, 0 if none */
/* Temperature of an axis the next cycle uses: its latest reading from the
 * temperature frame, else axis temp_c; m°C (0 for a bad axis/NULL). */
int32_t abbe_can_node_temp_mdegc(const abbe_can_node_t *node, unsigned axis);
/* Cycles since the axis' last temperature reading; axis ABBE_AXES: since the
 * last temperature frame (UINT32_MAX: never). */
uint32_t abbe_can_node_temp_age(const abbe_can_node_t *node, unsigned axis);
/* 1 if the last cycle's status frame reported TEMP_STALE (docs/can.md). */
int abbe_can_node_temp_stale(const abbe_can_node_t *node);
int abbe_can_node_last_load_status(const abbe_can_node_t *node);     /* 0 or the last failure */
/* The thermal runtime's state of the running model (abbe/thermal.h: flags,
 * channels), NULL without a thermal block or without thermal frames. */
const abbe_thermal_state_t *abbe_can_node_thermal(const abbe_can_node_t *node);

/* ---- status and info frames (layout documented in docs/abbe.dbc) -------- */

#define ABBE_CAN_STATUS_DLC 8u
#define ABBE_CAN_INFO_DLC 8u

typedef struct {
    uint8_t state;           /* abbe_comp_state_t */
    uint8_t model_loaded;
    uint8_t load_failed;     /* the last model load was refused */
    uint8_t fresh_mask;      /* bit j: axis j had a fresh position this cycle */
    uint8_t temp_stale;      /* temperatures not current (temperature frame enabled) */
    uint16_t flags;          /* ABBE_FLAG_* (low 16 bits) */
    uint8_t seq;             /* cycle counter, wraps */
    uint8_t age[ABBE_AXES];  /* cycles since the axis' last position, saturated at 255 */
    uint8_t ignored;         /* ignored frames, modulo 256 */
} abbe_can_status_frame_t;

typedef struct {
    uint32_t model_crc;      /* running model's CRC-32, 0 if none */
    int8_t load_status;      /* 0, or the status of the last refused model */
    uint8_t model_swaps;     /* models taken into use, modulo 256 */
    uint16_t ignored;        /* ignored frames, saturated at 65535 */
} abbe_can_info_frame_t;

/* Decode a status / info frame payload (for tools and tests); ABBE_CAN_E_ARG
 * for a NULL pointer or a DLC other than 8. */
int abbe_can_status_decode(const abbe_can_frame_t *f, abbe_can_status_frame_t *s);
int abbe_can_info_decode(const abbe_can_frame_t *f, abbe_can_info_frame_t *s);

#endif /* ABBE_CAN_H */
