/* abbe LinuxCNC port: the compensator as LinuxCNC's servo thread sees it.
 *
 * This is the part of the HAL component (port/linuxcnc/abbe.comp) that has no
 * LinuxCNC dependency, so it is built and unit-tested by CMake with the
 * project's strict warnings. The .comp only copies HAL pins into
 * abbe_lcnc_input_t, calls abbe_lcnc_step() and copies abbe_lcnc_output_t back.
 *
 * What it adds to abbe_comp_t (docs/linuxcnc.md has the reasons):
 *   - HAL units: double mm / degrees C / seconds in, mm and counts out; the
 *     limits, rate and fade are given in mm, mm/s and s and turned into the
 *     compensator's nm per cycle with the thread period of every call, so a
 *     change takes effect through abbe_comp_set_config() (no jump);
 *   - enable, homed, machine-on and reset pins mapped onto enable / disable /
 *     reset of the compensator;
 *   - a lead: LinuxCNC applies an external offset two servo periods after
 *     the commanded position it was computed for (one period from the counts
 *     to motion's offset register, one in its offset planner), so the model
 *     is evaluated where the axis will be then: p + lead * (p - p_previous),
 *     in integer nm (lead_periods, default 2; 0 evaluates at p);
 *   - a backlash direction per axis from the commanded positions (not the
 *     extrapolated ones), with a deadband (sticky: the last direction is kept
 *     while the axis stands); the library ramps its direction state by the
 *     extrapolated motion in that direction;
 *   - the s32 counts for axis.L.eoffset-counts. LinuxCNC accumulates count
 *     *changes* (times eoffset-scale), and only while it is on, homed and
 *     eoffset-enable is set; it zeroes its register at machine-on. The port
 *     mirrors that register (offset_mm) and writes each cycle the change that
 *     brings it to the correction, limited by the rate limit, so LinuxCNC's
 *     requested offset equals the correction whatever the history of machine
 *     off / on, homing and enable;
 *   - up to ABBE_LCNC_MAX_TABLES tables validated at load time; table-select
 *     swaps between them at a cycle boundary (abbe_comp_swap_model);
 *   - five-axis mode (docs/linuxcnc.md, "Five-axis machines"), chosen by the
 *     tables (format 1.2 with a rotary section; all tables of one kind): the
 *     inputs are the JOINT positions X, Y, Z, tilt, C, the library's
 *     abbe_comp_step5_* corrects the tool tip through X, Y, Z in the joint
 *     (machine) frame, and the port turns that correction into the frame of
 *     LinuxCNC's world coordinates, where external offsets are added before
 *     the inverse kinematics: under identity kinematics world = joints (the
 *     correction as it is); under the trt kinematics (tool-centre-point)
 *     world = workpiece coordinates and a world offset e moves the joints by
 *     R_tilt(t) Rz(c) e, so the port writes Rz(c)^T R_tilt(t)^T correction.
 *     Which kinematics is in force comes from the kinstype input (the value
 *     motion.switchkins-type gets); a value that is neither kins_identity nor
 *     kins_tcp is an invalid input (hold, then fade out after stale_s).
 *
 * No heap, no I/O, no libm: abbe_lcnc_step() runs in bounded time (the
 * library's evaluation plus a few dozen operations).
 */
#ifndef ABBE_LCNC_H
#define ABBE_LCNC_H

#include <stddef.h>
#include <stdint.h>

#include "abbe/abbe.h"

#define ABBE_LCNC_MAX_TABLES 4
#define ABBE_LCNC_TH_INPUTS 17 /* thermal block inputs (format 1.3): 16 temperatures + spindle speed */
#define ABBE_LCNC_TH_CHANNELS 5
/* The largest valid table is about 6 KiB (40 rows x 6 terms x 3 axes, two
 * arrays); a file may carry padding up to this size. */
#define ABBE_LCNC_TABLE_MAX_BYTES 65536u

/* Port flags, reported above the library's ABBE_FLAG_* bits in output.flags. */
#define ABBE_LCNC_FLAG_CONFIG 0x00010000u       /* a parameter is out of range: the last valid configuration stays */
#define ABBE_LCNC_FLAG_TABLE_SELECT 0x00020000u /* table-select names no loaded table: the running one stays */
#define ABBE_LCNC_FLAG_HOLD 0x00040000u         /* LinuxCNC takes no offset changes now (machine off or not homed) */
#define ABBE_LCNC_FLAG_CATCHUP 0x00080000u      /* LinuxCNC's offset is still moving to the correction at the rate limit */
#define ABBE_LCNC_FLAG_KINS 0x00100000u         /* five-axis: kinstype names neither kins_identity nor kins_tcp */

/* Frame of the external offsets (output.frame). */
#define ABBE_LCNC_FRAME_JOINTS 0     /* identity kinematics (and every 3-axis table): world = joints */
#define ABBE_LCNC_FRAME_WORKPIECE 1  /* trt kinematics, tool-centre-point: world = workpiece coordinates */
#define ABBE_LCNC_FRAME_UNKNOWN (-1) /* kinstype names no known kinematics: the correction fades out */

typedef enum {
    ABBE_LCNC_VARIANT_Q = 0,  /* abbe_comp_step_q: positions as integer nm (default) */
    ABBE_LCNC_VARIANT_F32 = 1 /* abbe_comp_step_f32: positions as float mm */
} abbe_lcnc_variant_t;

/* The HAL parameters, in the units of their names. */
typedef struct {
    double warn_mm[ABBE_AXES];       /* warning limit on |correction| (> 0) */
    double limit_mm[ABBE_AXES];      /* error limit: fault, fade out (>= warn) */
    double rate_mm_per_s[ABBE_AXES]; /* max correction speed (> 0) */
    int32_t sign[ABBE_AXES];         /* +1 or -1: correction = sign * -(dX, dY, dZ) */
    double fade_s;                   /* duration of a full fade in or out (>= 0) */
    double stale_s;                  /* invalid input for this long: fade out (>= 0) */
    double dir_deadband_mm;          /* motion that sets the backlash direction (>= 0) */
    double lead_periods;             /* evaluate this many periods ahead (0 .. 100), see below */
    double machine_unit_mm;          /* mm per LinuxCNC length unit: 1 (mm) or 25.4 (inch) */
    int32_t kins_identity;           /* five-axis: kinstype of identity kinematics (world = joints) */
    int32_t kins_tcp;                /* five-axis: kinstype of the trt kinematics (world = workpiece); != kins_identity */
    double thermal_sample_s;         /* a table's thermal block (format 1.3): the th-in pins are sampled
                                        this often, s (0.001 .. 3600; default 1) */
} abbe_lcnc_params_t;

/* One servo period's inputs. */
typedef struct {
    double pos_mm[ABBE_AXES];   /* 3-axis: commanded axis position (axis.L.pos-cmd); five-axis:
                                   commanded joint position X, Y, Z (joint.N.pos-cmd); mm */
    double angle_deg[ABBE_ROTARY_AXES]; /* five-axis: tilt (A or B) and C joint positions, degrees */
    double kinstype;            /* five-axis: the kinematics in force (motion.switchkins-type) */
    double temp_c[ABBE_AXES];   /* axis temperature, deg C (used if the table has THERMAL) */
    uint8_t axis_fault[ABBE_AXES]; /* 1: this axis' correction fades out */
    uint8_t enable;             /* compensation wanted */
    uint8_t homed;              /* every joint homed (motion.is-all-homed) */
    uint8_t machine_on;         /* motion enabled (motion.motion-enabled) */
    uint8_t reset;              /* rising edge clears a latched limit fault */
    int32_t table_select;       /* index of the table to run */
    double th_in[ABBE_LCNC_TH_INPUTS]; /* thermal block inputs: deg C, the speed input rpm */
    uint8_t th_fault[ABBE_LCNC_TH_INPUTS]; /* 1: no reading of that input (open circuit) */
} abbe_lcnc_input_t;

typedef struct {
    double corr_mm[ABBE_AXES];   /* correction (faded, rate limited), mm */
    double target_mm[ABBE_AXES]; /* what the model asks for (unfaded), mm */
    double offset_mm[ABBE_AXES]; /* LinuxCNC's requested external offset as the port tracks it, mm
                                    (world frame: see frame) */
    double orient_urad[3];       /* five-axis: tool orientation error the linear axes cannot correct
                                    (rotation vector, machine frame, as the model evaluates it), urad */
    int32_t frame;               /* ABBE_LCNC_FRAME_*: frame of offset_mm / counts */
    int32_t counts[ABBE_AXES];   /* for axis.L.eoffset-counts (1 count = 1 nm) */
    double eoffset_scale;        /* for axis.L.eoffset-scale: 1 nm in machine units */
    uint32_t flags;              /* ABBE_FLAG_* | ABBE_LCNC_FLAG_* */
    int32_t state;               /* abbe_comp_state_t: 0 off, 1 on, 2 fault */
    uint32_t model_crc;          /* CRC-32 of the running table */
    int32_t table_active;        /* index of the running table */
    uint8_t warning;             /* |target| above a warning limit */
    uint8_t fault;               /* error limit tripped (latched until reset) */
    uint8_t config_error;        /* parameters out of range (ABBE_LCNC_FLAG_CONFIG) */
    abbe_comp_stats_t stats;     /* the compensator's counters */
    uint32_t config_errors;      /* rejected parameter changes */
    uint32_t th_flags;           /* the thermal runtime's flags (ABBE_THERMAL_F_*), 0 without a block */
    uint32_t th_input_faults;    /* bit k: thermal input k faulted at the last sample */
    double th_channel[ABBE_LCNC_TH_CHANNELS]; /* thermal channel values, um (urad for tilts), unfaded */
    uint32_t th_samples;         /* thermal samples taken */
} abbe_lcnc_output_t;

/* Port state. Allocate it yourself (static storage in the HAL component); all
 * fields are private. */
typedef struct {
    abbe_comp_t comp;
    abbe_five_model_t model[ABBE_LCNC_MAX_TABLES]; /* a 3-axis table: its `linear` member only */
    abbe_thermal_model_t thermal[ABBE_LCNC_MAX_TABLES]; /* each table's thermal block (n_channels 0: none) */
    abbe_thermal_state_t th;  /* the running table's thermal runtime */
    int32_t th_table;         /* table th was started for, -1 none */
    int64_t th_clock_ns;      /* time since the last thermal sample */
    uint32_t th_samples;
    unsigned n_tables;
    uint32_t kind;           /* ABBE_KIN_* of every table (0: 3-axis) */
    int32_t active;          /* table running (or queued to run next cycle) */
    abbe_lcnc_variant_t variant;
    abbe_comp_config_t cfg;  /* configuration in force */
    int32_t deadband_nm;     /* backlash direction deadband in force */
    double eoffset_scale;    /* axis.L.eoffset-scale in force */
    int32_t kins_identity;   /* kinstype values in force */
    int32_t kins_tcp;
    int32_t frame;           /* ABBE_LCNC_FRAME_* of the offsets (the last known one) */
    double held_angle_deg[ABBE_ROTARY_AXES]; /* the last valid (lead) angles */
    abbe_lcnc_params_t params_seen;
    long period_seen_ns;
    uint8_t params_bad;      /* the parameters last seen did not convert */
    uint32_t config_errors;
    /* enable logic */
    uint8_t enabled;
    uint8_t prev_reset;
    uint8_t prev_machine_on;
    /* backlash direction */
    int32_t anchor_nm[ABBE_AXES];
    int8_t dir[ABBE_AXES];
    uint8_t have_anchor;
    /* lead */
    int32_t last_pos_nm[ABBE_AXES];
    double last_angle_deg[ABBE_ROTARY_AXES];
    uint8_t have_last;
    double lead_periods;     /* lead in force */
    /* LinuxCNC's external-offset register, mirrored */
    uint32_t counts[ABBE_AXES];   /* the s32 output, two's complement */
    int64_t accepted_nm[ABBE_AXES];
    int32_t pending_nm[ABBE_AXES];
} abbe_lcnc_t;

/* Defaults: warn 0.05 mm, limit 0.1 mm, rate 1 mm/s, sign +1, fade 0.5 s,
 * stale 0.01 s, deadband 0.0005 mm, lead 2 periods, machine unit 1 mm,
 * kins_identity 0, kins_tcp 1 (LinuxCNC's trt sample configurations, loaded
 * with sparm=identityfirst; without it trt is 0 and identity 1). */
void abbe_lcnc_default_params(abbe_lcnc_params_t *params);

/* The compensator configuration for params at a thread period. Returns
 * ABBE_OK, or ABBE_E_ARG (cfg untouched) for a NULL pointer, a period <= 0 or
 * a parameter outside its range (see abbe_lcnc_params_t). */
abbe_status_t abbe_lcnc_params_to_config(const abbe_lcnc_params_t *params, long period_ns,
                                         abbe_comp_config_t *cfg);

/* Start with no table, disabled, counts zero. The configuration is built for
 * period_ns (use the expected servo period; every step re-checks it).
 * Returns ABBE_E_ARG for NULL, an unknown variant or bad parameters. */
abbe_status_t abbe_lcnc_init(abbe_lcnc_t *port, abbe_lcnc_variant_t variant,
                             const abbe_lcnc_params_t *params, long period_ns);

/* Validate a table into the next slot (a 3-axis table: abbe_model_load; a
 * five-axis one: abbe_five_model_load, and the port runs in five-axis mode);
 * the first one added runs. blob must be 4-byte aligned and stay valid and
 * unchanged while the port lives. Returns ABBE_OK, the loader's status
 * (nothing added), or ABBE_E_ARG for NULL, no free slot or a table whose
 * kinematics (abbe_lcnc_blob_kind) differs from the first one's. Call before
 * the first step. */
abbe_status_t abbe_lcnc_add_table(abbe_lcnc_t *port, const void *blob, size_t size);

/* ABBE_KIN_* of a valid table (0 for a 3-axis one), or 0xFFFFFFFF if it is
 * not valid. */
uint32_t abbe_lcnc_blob_kind(const void *blob, size_t size);

/* ABBE_KIN_* of the tables added (0: 3-axis mode). */
uint32_t abbe_lcnc_kind(const abbe_lcnc_t *port);

/* Tables added. */
unsigned abbe_lcnc_table_count(const abbe_lcnc_t *port);

/* CRC-32 of table i (0 if there is none). */
uint32_t abbe_lcnc_table_crc(const abbe_lcnc_t *port, unsigned i);

/* One servo period. params are the HAL parameters as they are now, period_ns
 * the thread period of this call. Always writes *out. */
void abbe_lcnc_step(abbe_lcnc_t *port, const abbe_lcnc_params_t *params, long period_ns,
                    const abbe_lcnc_input_t *in, abbe_lcnc_output_t *out);

#endif /* ABBE_LCNC_H */
