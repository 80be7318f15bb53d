/* abbe grblHAL plugin: the part without a grblHAL dependency.
 *
 * port/grblhal/src/abbe_grblhal.c installs this on grblHAL's kinematics
 * interface; everything here is plain C99 on the abbe library, so it is
 * unit-tested and benchmarked (Cortex-M4F / M3 under QEMU) without grblHAL.
 *
 * Model: the motors are commanded to m = p + c(p), c = -E(p) the correction of
 * the library's compensator (abbe_comp_t: maximum correction, rate limit,
 * fade in / out, fault latch), evaluated once per segment end. Between two
 * segment ends the motors move on a straight line, so a line is split into
 * segments short enough that the model's deviation from that chord stays below
 * a bound: |c(a + t(b - a)) - chord| <= L^2 / 8 * kappa for a segment of length
 * L, kappa the largest second derivative of E along any direction over the
 * table's travel (sampled at load, abbe_gh_curvature). L = sqrt(8 dev / kappa).
 * A reversal of an axis with a backlash take-up gets a segment end where the
 * take-up ends (the direction state ramps linearly over it), and a line that
 * crosses a face of the table's travel box one where it crosses (the library
 * holds each term at its end value beyond: a kink).
 *
 * Variant: the _f32 evaluation where there is an FPU (or on a host), _q
 * (integer nm) otherwise; ABBE_GH_FIXED_POINT=1 forces _q.
 * No heap, no I/O; the caller owns abbe_gh_t.
 */
#ifndef ABBE_GRBLHAL_CORE_H
#define ABBE_GRBLHAL_CORE_H

#include <stddef.h>
#include <stdint.h>

#include "abbe/abbe.h"

#ifndef ABBE_GH_FIXED_POINT
#if defined(__arm__) && !defined(__ARM_FP)
#define ABBE_GH_FIXED_POINT 1
#else
#define ABBE_GH_FIXED_POINT 0
#endif
#endif

/* Largest table an upload may stage, bytes (a table of the largest shape,
 * 40 rows x 6 terms x 3 axes in two arrays plus reversal blocks, is ~6 KiB). */
#ifndef ABBE_GH_TABLE_MAX_BYTES
#define ABBE_GH_TABLE_MAX_BYTES 8192u
#endif

/* Segment length limits, mm: never shorter (planner throughput), never longer
 * (a table with almost no curvature still gets fresh corrections). */
#define ABBE_GH_SEG_MIN_MM 0.05f
#define ABBE_GH_SEG_MAX_MM 25.0f

typedef enum {
    ABBE_GH_OFF = 0,    /* disabled and faded out: lines pass through unchanged */
    ABBE_GH_ON = 1,     /* enabled, full correction */
    ABBE_GH_FADING = 2, /* fading in or out */
    ABBE_GH_FAULT = 3   /* a fault latched: faded out / fading out, lines pass through once at zero */
} abbe_gh_state_t;

/* User parameters (grblHAL $ settings). */
typedef struct {
    float max_dev_um;       /* bound on the correction's deviation along a segment, um (> 0) */
    float limit_um;         /* largest correction per axis, um: beyond it a fault latches (> 0) */
    float rate_um_per_seg;  /* largest change of the correction from one segment end to the next, um */
    uint16_t fade_segments; /* segments of a full fade in or out (>= 1) */
} abbe_gh_params_t;

/* Upload staging (docs/grblhal.md): chunks in order into the slot not running. */
typedef struct {
    uint32_t size;      /* announced size, bytes (0: nothing staged) */
    uint32_t crc;       /* announced CRC-32 (zlib) of the whole blob */
    uint32_t received;  /* bytes received so far */
    uint8_t slot;       /* slot being filled */
    uint8_t open;       /* 1 between begin and commit / abort */
    char why[72];       /* a refusal that names numbers (the size and the limit) */
} abbe_gh_stage_t;

/* One table slot: a loaded model over its blob, and its derived segment length. */
typedef struct {
    abbe_model_t model;
    float kappa_um_per_mm2;
    float takeup_mm[ABBE_AXES];
    float tref_c[ABBE_AXES];
    float travel_lo_mm[ABBE_AXES]; /* the table's travel: beyond it the library holds each term */
    float travel_hi_mm[ABBE_AXES];
    uint8_t loaded;
    abbe_thermal_model_t thermal; /* the table's thermal block (format 1.3; n_channels 0: none) */
    uint32_t blob[ABBE_GH_TABLE_MAX_BYTES / 4u]; /* uploaded / stored tables; a compiled-in one stays in
                                                    flash. Last: abbe_gh_init keeps it (abbe_gh_boot_buffer) */
} abbe_gh_slot_t;

/* A line split into segments (abbe_gh_line_begin / abbe_gh_line_next): into
 * pieces at the end of a backlash take-up and where the line crosses a face
 * of the table's travel box (the model has a kink there: its curvature does
 * not bound a chord across it), each piece into equal segments no longer
 * than the segment length. */
#define ABBE_GH_LINE_PIECES 10u /* per axis a take-up end and 2 faces, + the line's end */
typedef struct {
    float start[ABBE_AXES];
    float end[ABBE_AXES];
    float t_end[ABBE_GH_LINE_PIECES]; /* line parameter where each piece ends (ascending; last: 1) */
    uint32_t n[ABBE_GH_LINE_PIECES];  /* equal segments in each piece (>= 1) */
    uint32_t pieces;                  /* pieces in all */
    uint32_t piece;                   /* piece of the next segment */
    uint32_t k;                       /* segments returned from that piece */
    uint32_t i;                       /* segments returned so far */
    uint32_t total;                   /* segments in all */
} abbe_gh_line_t;

typedef struct {
    abbe_comp_t comp;
    abbe_gh_slot_t slot[2];
    abbe_gh_params_t params;
    abbe_gh_stage_t stage;
    uint8_t running;          /* slot of the model in use, 0xFF: none */
    uint8_t pending;          /* slot queued for the next segment, 0xFF: none */
    uint8_t enabled;          /* what the user asked for */
    uint8_t have_last;
    float seg_len_mm;         /* segment length in use */
    float last_cart[ABBE_AXES];   /* last segment end, Cartesian mm */
    int32_t last_corr_nm[ABBE_AXES]; /* correction applied there, nm */
    int8_t last_dir[ABBE_AXES];   /* sign of each axis' last motion (kept at standstill) */
    uint32_t flags;           /* compensator flags of the last segment (ABBE_FLAG_*) */
    abbe_comp_state_t comp_state;
    uint32_t segments;        /* segment ends computed since init */
    /* thermal block of the running table (abbe_gh_thermal_sample, docs/grblhal.md) */
    abbe_thermal_state_t thermal;
    uint32_t now_ms;          /* grblHAL's millisecond clock (abbe_gh_clock) */
    uint32_t thermal_apply_ms; /* clock at the last segment end's thermal apply */
    uint32_t thermal_sample_ms; /* clock at the last sample */
    uint8_t thermal_on;       /* the running table has a thermal block */
    uint8_t thermal_applied;  /* thermal_apply_ms is set */
    uint8_t thermal_sampled;  /* thermal_sample_ms is set */
} abbe_gh_t;

/* Defaults: 1 um deviation, 200 um limit, 10 um per segment, fade over 32 segments. */
void abbe_gh_default_params(abbe_gh_params_t *params);

/* Start with params (checked: ABBE_E_ARG if out of range) and, if blob is not
 * NULL, that table in slot 0 (a compiled-in table: used in place, it must stay
 * valid). Disabled; abbe_gh_set_enabled() fades in. A table that fails to
 * validate returns its status and leaves the plugin without a model (it then
 * passes lines through). */
abbe_status_t abbe_gh_init(abbe_gh_t *gh, const abbe_gh_params_t *params, const void *blob, size_t size);

/* Slot 0's RAM: read a stored table there, then abbe_gh_init(gh, params,
 * abbe_gh_boot_buffer(gh), size) validates it in place (init keeps a blob
 * that already lies in this buffer). ABBE_GH_TABLE_MAX_BYTES long. */
uint8_t *abbe_gh_boot_buffer(abbe_gh_t *gh);

/* The machine was homed (or its position set without motion): the correction
 * restarts from zero where the motors stand, so the reported position is
 * grblHAL's own there, and fades in again over fade_segments if enabled. The
 * motors do not move, so nothing jumps. A queued table becomes the running
 * one. A latched fault stays latched (the correction is already fading to
 * zero). */
abbe_status_t abbe_gh_rehome(abbe_gh_t *gh);

/* Change the parameters of a running plugin (no jump: abbe_comp_set_config). */
abbe_status_t abbe_gh_set_params(abbe_gh_t *gh, const abbe_gh_params_t *params);

/* Enable (fade in) / disable (fade out); 2 = clear a latched fault and disable. */
abbe_status_t abbe_gh_set_enabled(abbe_gh_t *gh, int enable);

/* The state the status report shows. */
abbe_gh_state_t abbe_gh_state(const abbe_gh_t *gh);

/* 1 if lines must go through the compensator (a model is loaded and a
 * correction is on or still fading out), 0 if they pass through unchanged. */
int abbe_gh_active(const abbe_gh_t *gh);

/* The largest second derivative (um/mm^2) of the model's error along any
 * direction, sampled inside the table's travel: per sample point the largest
 * Gershgorin row sum of the three Hessians (one per error component), by
 * differences over h = min(travel / 256, 0.5 mm, a quarter of the shortest
 * travel) at 255 points from lo + h to hi - h on lines along each axis through
 * the corners of the travel box of the other two, inset by h (each term
 * depends on one axis and enters with a lever arm linear in the others, so the
 * extremes lie on those lines). Every point of the stencil lies inside the
 * travel: beyond it the library holds each term at its end value, a kink
 * (the line segmentation ends a segment there), not a curvature. Costs 30,600
 * evaluations (ABBE_GH_CURV_SAMPLES = 256 points per line). */
abbe_status_t abbe_gh_curvature(const abbe_model_t *model, float *kappa_um_per_mm2);

/* Segment length for deviation bound dev_um and curvature kappa, mm, within
 * [ABBE_GH_SEG_MIN_MM, ABBE_GH_SEG_MAX_MM]. */
float abbe_gh_segment_length(float dev_um, float kappa_um_per_mm2);

/* The deviation bound actually met with segments of len_mm: len^2 / 8 * kappa, um. */
float abbe_gh_deviation_um(float len_mm, float kappa_um_per_mm2);

/* Split the line start -> end (Cartesian mm) into segments (see the header
 * comment); returns the number of segments (>= 1). */
uint32_t abbe_gh_line_begin(const abbe_gh_t *gh, abbe_gh_line_t *line, const float start[ABBE_AXES],
                            const float end[ABBE_AXES]);

/* Next segment end (Cartesian mm) into out; 0 when the line is done. The last
 * one is exactly line->end. */
int abbe_gh_line_next(abbe_gh_line_t *line, float out[ABBE_AXES]);

/* One segment end: direction from the motion since the last one, one
 * compensator step, motor = cart + correction (mm). Returns the compensator
 * flags (ABBE_FLAG_*). */
uint32_t abbe_gh_forward(abbe_gh_t *gh, const float cart[ABBE_AXES], float motor[ABBE_AXES]);

/* Cartesian position of motor position motor (mm): the fixed point of
 * q = motor - c(q), c(q) = the correction applied at the last segment end plus
 * the model's change from there to q (so it is exact where motion stopped,
 * also in the middle of a fade). At most 4 iterations (each shrinks the error
 * by |dE/dp| ~ 1e-4). Returns the iterations used. */
int abbe_gh_inverse(const abbe_gh_t *gh, const float motor[ABBE_AXES], float cart[ABBE_AXES]);

/* Tell the plugin where the machine is after a jump it did not command
 * (homing, reset): the next line starts there. */
void abbe_gh_set_position(abbe_gh_t *gh, const float cart[ABBE_AXES]);

/* Upload: begin (size, CRC-32 of the blob), data in order, commit (validate
 * into the slot not running and queue it for the next segment) or abort.
 * Every failure leaves the running table as it is; *why gets a short reason. */
abbe_status_t abbe_gh_upload_begin(abbe_gh_t *gh, uint32_t size, uint32_t crc, const char **why);
abbe_status_t abbe_gh_upload_data(abbe_gh_t *gh, uint32_t offset, const uint8_t *data, uint32_t n,
                                  const char **why);
abbe_status_t abbe_gh_upload_commit(abbe_gh_t *gh, const char **why);
void abbe_gh_upload_abort(abbe_gh_t *gh);

/* A table kept in non-volatile storage (docs/grblhal.md): a 16-byte header
 * then the blob. Header, little-endian: magic "ABT1", the blob's size, its
 * CRC-32 (zlib), and the CRC-32 of those 12 bytes. A writer invalidates the
 * header first (zeros), writes the blob, then the header, so an interrupted
 * write leaves no valid record. */
#define ABBE_GH_STORE_HEADER_BYTES 16u
#define ABBE_GH_STORE_MAGIC 0x31544241u /* "ABT1" */

typedef enum {
    ABBE_GH_STORE_NONE = 0,    /* erased or invalidated: no table stored */
    ABBE_GH_STORE_VALID = 1,   /* header valid: size and CRC of the blob to read */
    ABBE_GH_STORE_CORRUPT = 2  /* a header that is neither: *why says what is wrong */
} abbe_gh_store_t;

void abbe_gh_store_header(uint8_t out[ABBE_GH_STORE_HEADER_BYTES], uint32_t size, uint32_t crc);

/* Parse a header read from storage; capacity: the largest blob the storage
 * holds (bytes). A valid header gives *size (16 .. min(capacity,
 * ABBE_GH_TABLE_MAX_BYTES)) and *crc. */
abbe_gh_store_t abbe_gh_store_parse(const uint8_t in[ABBE_GH_STORE_HEADER_BYTES], uint32_t capacity,
                                    uint32_t *size, uint32_t *crc, const char **why);

/* ---- thermal block (format 1.3 tables; docs/grblhal.md "Temperatures") ----
 * The running table's thermal block is advanced by real time: the glue sets
 * the clock (grblHAL's hal.get_elapsed_ticks(), ms) before every segment end
 * and every sample; each segment end adds the thermal error with
 * abbe_comp_step_thermal_ms_* (fades and the missing-sample watchdog by the
 * ms since the previous segment end), before the compensator's safety layer
 * (limit, rate per segment, fades). A table without a thermal block runs the
 * plain abbe_comp_step_* as before. A new table restarts the thermal state
 * (it fades in after its first sample). */
void abbe_gh_clock(abbe_gh_t *gh, uint32_t now_ms);

/* One temperature sample at the current clock: x[k] for every input of the
 * running table's thermal block, in its order (deg C for temperatures, rpm
 * for the spindle speed), valid_mask bit k = input k has a reading. dt is the
 * clock's change since the previous sample. ABBE_E_ARG with *why: no thermal
 * block, or a second sample in the same millisecond. Sensor faults are not
 * errors: they show in the flags (abbe_gh_thermal). */
abbe_status_t abbe_gh_thermal_sample(abbe_gh_t *gh, const float x[], uint32_t valid_mask, const char **why);

/* The running thermal state (NULL: the running table has no thermal block). */
const abbe_thermal_state_t *abbe_gh_thermal(const abbe_gh_t *gh);

/* The model in use (NULL: none) and its CRC (0: none). */
const abbe_model_t *abbe_gh_model(const abbe_gh_t *gh);

#endif /* ABBE_GRBLHAL_CORE_H */
