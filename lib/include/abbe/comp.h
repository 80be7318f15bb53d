/* abbe: the compensator, turning the model into safe axis corrections.
 *
 * Call abbe_comp_step_f32() or abbe_comp_step_q() once per interpolation cycle.
 * The safety layer follows what trusted controllers do (docs/concepts.md):
 *   - per-axis warning and error limits on the total correction; beyond the
 *     error limit the compensator latches a fault and fades to zero;
 *   - a rate limit on the correction change per cycle;
 *   - fade-in on enable, fade-out on disable, fault, axis fault or stale input,
 *     so a correction never appears or disappears with a jump;
 *   - a stale-input watchdog: no fresh positions for stale_cycles: fade out,
 *     flag; fresh positions again: fade back in;
 *   - model swap at a cycle boundary, only for a model that validated.
 * All state is in the caller-owned abbe_comp_t. Corrections are integers in nm
 * for both variants (a drive takes increments; ports scale them).
 */
#ifndef ABBE_COMP_H
#define ABBE_COMP_H

#include <stddef.h>
#include <stdint.h>

#include "abbe/error.h"
#include "abbe/model.h"
#include "abbe/five_axis.h"

/* C linkage for C++ callers (firmware in C++ links the C library). */
#ifdef __cplusplus
extern "C" {
#endif

/* Compensator flags, reported with the evaluation flags (ABBE_FLAG_*). */
#define ABBE_FLAG_WARN 0x0010u          /* |correction target| above the warning limit */
#define ABBE_FLAG_LIMIT 0x0020u         /* error limit exceeded: fault latched (until abbe_comp_reset) */
#define ABBE_FLAG_RATE_LIMITED 0x0040u  /* an output change was clipped by the rate limit */
#define ABBE_FLAG_STALE 0x0080u         /* no fresh input for stale_cycles */
#define ABBE_FLAG_FADING 0x0100u        /* some axis gain is between 0 and 1 */
/* ABBE_FLAG_INPUT_INVALID (0x0200, abbe/error.h): this cycle's input was NaN/Inf or marked not fresh */
#define ABBE_FLAG_MODEL_SWAPPED 0x0400u /* a new model took effect this cycle */
#define ABBE_FLAG_NO_MODEL 0x0800u      /* no model: output fades to zero */
#define ABBE_FLAG_AXIS_FAULT 0x1000u    /* the caller reported an axis fault */

typedef enum {
    ABBE_COMP_OFF = 0,    /* disabled, corrections zero (or fading out) */
    ABBE_COMP_ON = 1,     /* enabled (possibly fading in, stale or limited: see flags) */
    ABBE_COMP_FAULT = 2   /* error limit tripped: fading out / zero until abbe_comp_reset() */
} abbe_comp_state_t;

typedef struct {
    int32_t warn_nm[ABBE_AXES];           /* warning limit on |correction|, > 0 */
    int32_t limit_nm[ABBE_AXES];          /* error limit on |correction|, >= warn_nm */
    int32_t rate_nm_per_cycle[ABBE_AXES]; /* max output change per cycle, > 0 */
    uint16_t fade_cycles;                 /* cycles of a full fade in or out, >= 1 */
    uint16_t stale_cycles;                /* cycles without fresh input before fading out, >= 1 */
    int8_t axis_sign[ABBE_AXES];          /* +1 or -1: correction = sign * -(dX, dY, dZ) */
} abbe_comp_config_t;

/* Per-cycle input. dir: -1 moving -, +1 moving +, 0 standstill (the backlash
 * direction state keeps its value; while moving it ramps toward dir over the
 * table's take-up distance). fresh: 1 if the positions are new this cycle.
 * axis_fault_mask: bit j set = axis j faulted, its correction fades out. */
typedef struct {
    float pos_mm[ABBE_AXES];
    float temp_c[ABBE_AXES];
    int8_t dir[ABBE_AXES];
    uint8_t fresh;
    uint8_t axis_fault_mask;
} abbe_comp_input_f32_t;

typedef struct {
    abbe_nm_t pos_nm[ABBE_AXES];
    int32_t temp_mdegc[ABBE_AXES];
    int8_t dir[ABBE_AXES];
    uint8_t fresh;
    uint8_t axis_fault_mask;
} abbe_comp_input_q_t;

typedef struct {
    int32_t corr_nm[ABBE_AXES];   /* correction to add to the commanded axis positions, nm */
    int32_t target_nm[ABBE_AXES]; /* unfaded, unlimited correction the model asks for, nm */
    uint32_t flags;               /* ABBE_FLAG_* */
    abbe_comp_state_t state;
} abbe_comp_output_t;

typedef struct {
    uint32_t cycles;         /* steps taken */
    uint32_t invalid_inputs; /* cycles with NaN/Inf or not-fresh input */
    uint32_t stale_events;   /* transitions into stale */
    uint32_t limit_trips;    /* error-limit faults */
    uint32_t rate_limited;   /* cycles with a clipped output */
    uint32_t model_swaps;    /* models taken into use */
} abbe_comp_stats_t;

/* Compensator state. Allocate it yourself; all fields are private. */
typedef struct {
    abbe_comp_config_t cfg;
    const abbe_model_t *model;
    const abbe_model_t *pending;
    uint32_t gain_step_q16;
    uint32_t gain_q16[ABBE_AXES];
    int32_t out_nm[ABBE_AXES];
    int32_t target_nm[ABBE_AXES];
    int32_t fault_from_nm[ABBE_AXES]; /* output when the fault latched: the fade-out starts there */
    int32_t last_pos_nm[ABBE_AXES];
    int32_t dir_state_q30[ABBE_AXES];
    uint32_t eval_flags;
    uint16_t stale_count;
    uint8_t have_pos;
    uint8_t enabled;
    uint8_t fault;
    uint8_t stale;
    abbe_comp_stats_t stats;
    /* Working memory of one cycle's evaluation, kept here rather than on the
     * stack: a cycle's stack stays within 256 B (3-axis) and 320 B (five-axis
     * _f32, bench/results.md section 11). A cycle uses one member: q the 18
     * term values and the error (the fixed-point cycles); five_f32 the
     * positions (nm) and angles (micro-degrees), the direction states as
     * floats, the evaluation's output and the error (abbe_comp_step5_f32). */
    union {
        int32_t q[ABBE_AXES * ABBE_TERMS + ABBE_AXES];
        struct {
            int32_t at[ABBE_AXES + ABBE_ROTARY_AXES];
            float dir_state[ABBE_AXES];
            abbe_five_error_f32_t eval;
            int32_t error_nm[ABBE_AXES];
        } five_f32;
    } scratch;
} abbe_comp_t;

/* Check cfg and start disabled with zero corrections. model may be NULL (no
 * model yet). Returns ABBE_E_ARG for NULL comp/cfg or a config value outside
 * its documented range (comp is then left untouched). */
abbe_status_t abbe_comp_init(abbe_comp_t *comp, const abbe_comp_config_t *cfg,
                             const abbe_model_t *model);

/* Replace the configuration of a running compensator (limits, rates, fades,
 * watchdog, axis signs) without touching its state: the outputs, gains,
 * backlash direction states, model and counters go on; the new rate limit and
 * fade apply from the next step, so the change itself causes no jump. A
 * latched limit fault stays latched until abbe_comp_reset(). Returns
 * ABBE_E_ARG (config unchanged) for NULL or an out-of-range value. */
abbe_status_t abbe_comp_set_config(abbe_comp_t *comp, const abbe_comp_config_t *cfg);

/* Enable: corrections fade in over fade_cycles. Disable: they fade out. */
abbe_status_t abbe_comp_enable(abbe_comp_t *comp);
abbe_status_t abbe_comp_disable(abbe_comp_t *comp);

/* Clear a latched limit fault and disable; the output fades out from where it
 * is (no jump). Enable again to resume. */
abbe_status_t abbe_comp_reset(abbe_comp_t *comp);

/* Queue an already loaded model; it takes effect at the start of the next
 * step. The model must stay valid while in use. */
abbe_status_t abbe_comp_swap_model(abbe_comp_t *comp, const abbe_model_t *model);

/* Validate blob into *slot and, only if it is valid, queue *slot as the next
 * model. slot must not be the running or queued model (ABBE_E_ARG). On a
 * validation failure the status says why, *slot is untouched and the running
 * model goes on. */
abbe_status_t abbe_comp_load_model(abbe_comp_t *comp, abbe_model_t *slot, const void *blob,
                                   size_t size);

/* Model in use (NULL if none); the queued one is not reported until it runs. */
const abbe_model_t *abbe_comp_model(const abbe_comp_t *comp);

/* One cycle. Always writes a safe *out (ABBE_OK), even for bad input, which is
 * reported in out->flags; returns ABBE_E_ARG only for NULL pointers. */
abbe_status_t abbe_comp_step_f32(abbe_comp_t *comp, const abbe_comp_input_f32_t *in,
                                 abbe_comp_output_t *out);
abbe_status_t abbe_comp_step_q(abbe_comp_t *comp, const abbe_comp_input_q_t *in,
                               abbe_comp_output_t *out);

/* ---- five-axis machines (abbe/five_axis.h) ----
 * The same compensator (limits, rate, fade, watchdog, atomic swap) with the
 * tool tip's position error as its target: it corrects X, Y, Z; the tool's
 * orientation error, which X, Y, Z cannot correct, is reported beside.
 * abbe_comp_step_f32/_q on a five-axis model evaluate its linear axes only:
 * use abbe_comp_step5_* with a five-axis model. A 3-axis model under
 * abbe_comp_step5_* is evaluated as a five-axis table without rotary errors. */
typedef struct {
    abbe_comp_input_f32_t lin; /* X, Y, Z as for abbe_comp_step_f32 */
    float angle_deg[2];        /* tilt (A or B), C joint positions, degrees */
} abbe_comp_input5_f32_t;

typedef struct {
    abbe_comp_input_q_t lin;
    int32_t angle_udeg[2];     /* micro-degrees */
} abbe_comp_input5_q_t;

typedef struct {
    abbe_comp_output_t lin;    /* corrections of X, Y, Z as for the 3-axis step */
    int32_t orient_nrad[3];    /* the model's tool orientation error this cycle (not corrected), nrad; 0 without */
} abbe_comp_output5_t;

/* As abbe_comp_swap_model / abbe_comp_load_model, for a five-axis model. */
abbe_status_t abbe_comp_swap_five_model(abbe_comp_t *comp, const abbe_five_model_t *model);
abbe_status_t abbe_comp_load_five_model(abbe_comp_t *comp, abbe_five_model_t *slot, const void *blob,
                                        size_t size);

/* One cycle at joint positions (X, Y, Z, tilt, C); as abbe_comp_step_*. A
 * NaN/Inf angle is a bad input like a NaN position. */
abbe_status_t abbe_comp_step5_f32(abbe_comp_t *comp, const abbe_comp_input5_f32_t *in, abbe_comp_output5_t *out);
abbe_status_t abbe_comp_step5_q(abbe_comp_t *comp, const abbe_comp_input5_q_t *in, abbe_comp_output5_t *out);

/* sizeof(abbe_comp_t) as this library was built (for language bindings). */
size_t abbe_comp_sizeof(void);

/* Counters since init. */
abbe_comp_stats_t abbe_comp_stats(const abbe_comp_t *comp);

#ifdef __cplusplus
} /* extern "C" */
#endif

#endif /* ABBE_COMP_H */
