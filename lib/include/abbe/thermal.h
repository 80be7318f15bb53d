/* abbe: the dynamic thermal model at run time (table format 1.3, docs/thermal.md).
 *
 * A table of format 1.3 carries a thermal block (docs/table-format.md,
 * "Thermal block"): up to 17 inputs (temperatures, spindle speed), up to 5
 * channels (dX, dY, dZ in um; the spindle tilts A, B in urad, which move the
 * tool tip through the table's tool offset t_z), each channel up to 4 terms
 * gain x first-order lag(input rise, tau). The reference is
 * host_tools/abbe/model/thermal.py; the lag is discretised by backward Euler,
 *     s += dt / (tau + dt) * (u - s),     u = x - reference (K, or krpm),
 * which needs no exp() and takes any sample spacing; every state starts at its
 * input's first good rise.
 *
 * Two rates: abbe_thermal_update_*() when a temperature sample arrives (the
 * states, faults, limits); abbe_thermal_apply_*() at every evaluation (adds
 * the faded thermal error to (dX, dY, dZ): three additions while nothing
 * fades). Everything lives in caller-owned structs; no heap, no libm.
 *
 * Faults (per input, every sample): the port's valid bit clear (open circuit,
 * no reading), a value outside [valid_min, valid_max] or NaN, a step larger
 * than max_step from the previous reading, a stuck sensor (an input with a
 * stuck time in the block whose credible readings stayed within its stuck
 * resolution of one value for that long: a frozen converter repeats a value
 * a live sensor's noise would not); and a missing sample (no update for
 * max_gap: apply() notices it, update() sees dt > max_gap). A channel with a
 * faulty input holds its states and fades its part out over fade_s; when its
 * inputs are good again and the fade-out has reached 0, its states catch up
 * (one backward Euler step over the held time, stable for any length) and it
 * fades back in. So the thermal part never jumps: per evaluation it moves by
 * at most |y| x period / fade_s plus a sample's own lag increment.
 */
#ifndef ABBE_THERMAL_H
#define ABBE_THERMAL_H

#include <stddef.h>
#include <stdint.h>

#include "abbe/comp.h"
#include "abbe/model.h"
#include "abbe/status.h"

#ifdef __cplusplus
extern "C" {
#endif

#define ABBE_THERMAL_MAX_INPUTS 17   /* 16 temperatures + spindle speed */
#define ABBE_THERMAL_MAX_CHANNELS 5  /* x, y, z, a, b */
#define ABBE_THERMAL_MAX_TERMS 4     /* per channel */

/* Header feature bit of a table with a thermal block (format 1.3). */
#define ABBE_FEATURE_THERMAL_DYN 0x40u
#define ABBE_THERMAL_FORMAT_MINOR 3

enum { ABBE_THERMAL_TEMPERATURE = 0, ABBE_THERMAL_SPEED = 1 };            /* input kinds */
enum { ABBE_THERMAL_OUT_X = 0, ABBE_THERMAL_OUT_Y = 1, ABBE_THERMAL_OUT_Z = 2,
       ABBE_THERMAL_OUT_A = 3, ABBE_THERMAL_OUT_B = 4 };                    /* channel outputs */

/* Thermal flags (abbe_thermal_flags(): current; abbe_thermal_events(): sticky). */
#define ABBE_THERMAL_F_OPEN 0x01u    /* an input's valid bit was clear (open circuit, no reading) */
#define ABBE_THERMAL_F_RANGE 0x02u   /* an input outside [valid_min, valid_max] (or NaN / Inf) */
#define ABBE_THERMAL_F_STEP 0x04u    /* an input moved more than max_step since its previous reading */
#define ABBE_THERMAL_F_GAP 0x08u     /* no sample for longer than max_gap */
#define ABBE_THERMAL_F_LIMIT 0x10u   /* a channel was clamped to its limit */
#define ABBE_THERMAL_F_HOLD 0x20u    /* some channel holds its states (faulted, or waiting to fade back in) */
#define ABBE_THERMAL_F_FADING 0x40u  /* some channel's weight is between its ends */
#define ABBE_THERMAL_F_STUCK 0x80u   /* an input stayed within its stuck resolution for its stuck time */
#define ABBE_THERMAL_F_FAULTS 0x8Fu

/* The thermal block of a loaded table, copied out of the blob by
 * abbe_thermal_load() (the blob need not stay). All fields private. Integer
 * fields: milli-units of the input (m degC, or rpm = milli-krpm), ms, nm or
 * nrad, gains in 2^-16 um per unit (= 2^-16 nm per milli-unit). */
typedef struct {
    uint8_t n_inputs;   /* 0: the table has no thermal block */
    uint8_t n_channels;
    uint8_t kind[ABBE_THERMAL_MAX_INPUTS];
    uint8_t output[ABBE_THERMAL_MAX_CHANNELS];
    uint8_t n_terms[ABBE_THERMAL_MAX_CHANNELS];
    uint8_t term_input[ABBE_THERMAL_MAX_CHANNELS][ABBE_THERMAL_MAX_TERMS];
    uint32_t channel_inputs[ABBE_THERMAL_MAX_CHANNELS]; /* bit k: the channel reads input k */
    int32_t ref_milli[ABBE_THERMAL_MAX_INPUTS];
    int32_t vmin_milli[ABBE_THERMAL_MAX_INPUTS];
    int32_t vmax_milli[ABBE_THERMAL_MAX_INPUTS];
    int32_t max_step_milli[ABBE_THERMAL_MAX_INPUTS];
    uint32_t stuck_ms[ABBE_THERMAL_MAX_INPUTS];        /* 0: no stuck check */
    int32_t stuck_res_milli[ABBE_THERMAL_MAX_INPUTS];  /* still = within this of the anchor */
    uint32_t tau_ms[ABBE_THERMAL_MAX_CHANNELS][ABBE_THERMAL_MAX_TERMS];
    int32_t gain_q16[ABBE_THERMAL_MAX_CHANNELS][ABBE_THERMAL_MAX_TERMS];
    int32_t limit[ABBE_THERMAL_MAX_CHANNELS]; /* nm, or nrad for tilts */
    uint32_t max_gap_ms;
    uint32_t fade_ms;
    int32_t tool_z_nm;  /* the table's tool offset t_z (0 without TOOL_OFFSET) */
    /* float twins (the _f32 path): natural units (degC, rpm, s, um, urad, mm) */
    float ref[ABBE_THERMAL_MAX_INPUTS];
    float vmin[ABBE_THERMAL_MAX_INPUTS];
    float vmax[ABBE_THERMAL_MAX_INPUTS];
    float max_step[ABBE_THERMAL_MAX_INPUTS];
    float stuck_s[ABBE_THERMAL_MAX_INPUTS];
    float stuck_res[ABBE_THERMAL_MAX_INPUTS];
    float rise_scale[ABBE_THERMAL_MAX_INPUTS]; /* 1 (K), 0.001 (rpm -> krpm) */
    float tau_s[ABBE_THERMAL_MAX_CHANNELS][ABBE_THERMAL_MAX_TERMS];
    float gain[ABBE_THERMAL_MAX_CHANNELS][ABBE_THERMAL_MAX_TERMS];
    float limit_f[ABBE_THERMAL_MAX_CHANNELS];
    float max_gap_s;
    float tool_z_mm;
} abbe_thermal_model_t;

/* The run-time state of one model, caller-owned; all fields private.
 * Initialise it with abbe_thermal_init_f32 / _q, then use one variant only. */
typedef struct {
    const abbe_thermal_model_t *model;
    /* _f32 */
    float s[ABBE_THERMAL_MAX_CHANNELS][ABBE_THERMAL_MAX_TERMS]; /* lag states, K / krpm */
    float x_prev[ABBE_THERMAL_MAX_INPUTS];   /* previous reading (degC, rpm) */
    float x_anchor[ABBE_THERMAL_MAX_INPUTS]; /* the value the input has stayed near (stuck check) */
    float still_s[ABBE_THERMAL_MAX_INPUTS];  /* for how long */
    float age_s[ABBE_THERMAL_MAX_CHANNELS];  /* time since the channel's last state update */
    float y[ABBE_THERMAL_MAX_CHANNELS];      /* channel value after its limit (um, urad) */
    float tip[ABBE_THERMAL_MAX_CHANNELS];    /* its part of the tool tip error, um (axis tip_axis) */
    float w[ABBE_THERMAL_MAX_CHANNELS];      /* fade weight 0..1 */
    float out[3];                            /* sum of w x tip by axis, um */
    float fade_step;                         /* weight change per apply() */
    /* _q */
    int64_t sq[ABBE_THERMAL_MAX_CHANNELS][ABBE_THERMAL_MAX_TERMS]; /* lag states, milli-units x 2^12 */
    uint32_t wq28[ABBE_THERMAL_MAX_CHANNELS][ABBE_THERMAL_MAX_TERMS]; /* cached dt/(tau+dt), Q28 */
    uint32_t wq_dt_ms[ABBE_THERMAL_MAX_CHANNELS];                     /* the dt that cache is for */
    int32_t xq_prev[ABBE_THERMAL_MAX_INPUTS];
    int32_t xq_anchor[ABBE_THERMAL_MAX_INPUTS];
    uint32_t still_ms[ABBE_THERMAL_MAX_INPUTS];
    uint32_t age_ms[ABBE_THERMAL_MAX_CHANNELS];
    int32_t yq[ABBE_THERMAL_MAX_CHANNELS];   /* nm / nrad */
    int32_t tipq[ABBE_THERMAL_MAX_CHANNELS]; /* nm */
    uint32_t wq24[ABBE_THERMAL_MAX_CHANNELS]; /* fade weight, 2^24 = 1 */
    int32_t outq[3];                          /* nm */
    uint32_t fade_step_q24;
    /* shared */
    uint32_t since_update;  /* apply() calls since the last update */
    uint32_t gap_calls;     /* apply() calls that make max_gap */
    uint32_t input_fault;   /* bit k: input k faulted at the last sample */
    uint32_t seen;          /* bit k: input k had a reading */
    uint32_t flags;         /* current ABBE_THERMAL_F_* */
    uint32_t events;        /* sticky ABBE_THERMAL_F_* since abbe_thermal_clear_events() */
    uint8_t ch_state[ABBE_THERMAL_MAX_CHANNELS]; /* 0 not started, 1 running, 2 holding */
    uint8_t tip_axis[ABBE_THERMAL_MAX_CHANNELS];
    uint8_t fading;
    uint8_t gap;
} abbe_thermal_state_t;

/* Validate blob[0 .. size) as a table of format 1.0, 1.1 or 1.3 (every check of
 * abbe_model_load, then the thermal block's, docs/table-format.md) and fill
 * *model (a view of the blob, as abbe_model_load) and *thermal (a copy;
 * n_channels = 0 for a table without a thermal block). On failure both are left
 * untouched. A five-axis table (ROTARY) is refused with ABBE_E_FLAGS. */
abbe_status_t abbe_thermal_load(abbe_model_t *model, abbe_thermal_model_t *thermal, const void *blob,
                                size_t size);

/* Start a state for thermal (no channel running, weights 0: the thermal part
 * fades in after the first good sample). period: the time between two apply()
 * calls (s > 0, finite / us >= 1). ABBE_E_ARG for NULL or a bad period. */
abbe_status_t abbe_thermal_init_f32(abbe_thermal_state_t *st, const abbe_thermal_model_t *thermal,
                                    float period_s);
abbe_status_t abbe_thermal_init_q(abbe_thermal_state_t *st, const abbe_thermal_model_t *thermal,
                                  uint32_t period_us);

/* One temperature sample: x[k] for every input of the model (degC or rpm;
 * _q: m degC or rpm), valid_mask bit k = the port has a reading of input k,
 * dt = time since the previous sample (ignored for the first; s > 0 / ms >= 1).
 * Returns ABBE_OK (faults are in the flags), ABBE_E_ARG for NULL or a bad dt
 * (the state is then unchanged). */
abbe_status_t abbe_thermal_update_f32(abbe_thermal_state_t *st, const float x[], uint32_t valid_mask,
                                      float dt_s);
abbe_status_t abbe_thermal_update_q(abbe_thermal_state_t *st, const int32_t x_milli[], uint32_t valid_mask,
                                    uint32_t dt_ms);

/* Every evaluation: add the faded thermal error to err (dX, dY, dZ; um / nm). */
void abbe_thermal_apply_f32(abbe_thermal_state_t *st, float err_um[3]);
void abbe_thermal_apply_q(abbe_thermal_state_t *st, int32_t err_nm[3]);

/* The same with the fades and the missing-sample watchdog advanced by real
 * time instead of one period: elapsed_ms since the previous apply (0 is
 * fine: nothing advances), for a caller that evaluates at irregular
 * instants (the grblHAL plugin: once per planner segment). The weights then
 * move by at most elapsed_ms / fade_ms per call, and a missing sample is
 * flagged once more than max_gap_ms have passed since the last update().
 * A state is driven by apply() or by apply_ms(), never both (the period
 * given to init is then unused). */
void abbe_thermal_apply_ms_f32(abbe_thermal_state_t *st, float err_um[3], uint32_t elapsed_ms);
void abbe_thermal_apply_ms_q(abbe_thermal_state_t *st, int32_t err_nm[3], uint32_t elapsed_ms);

/* Channel values after their limits, unfaded (um / urad; _q nm / nrad), in the
 * table's channel order; returns the channel count. */
unsigned abbe_thermal_channels_f32(const abbe_thermal_state_t *st, float y[ABBE_THERMAL_MAX_CHANNELS]);
unsigned abbe_thermal_channels_q(const abbe_thermal_state_t *st, int32_t y[ABBE_THERMAL_MAX_CHANNELS]);

/* Current flags; sticky events (cleared by abbe_thermal_clear_events); the
 * inputs that faulted at the last sample (bit k). NULL gives 0. */
uint32_t abbe_thermal_flags(const abbe_thermal_state_t *st);
uint32_t abbe_thermal_events(const abbe_thermal_state_t *st);
void abbe_thermal_clear_events(abbe_thermal_state_t *st);
uint32_t abbe_thermal_input_faults(const abbe_thermal_state_t *st);
/* Inputs (n) and channels of a loaded thermal model (0 without a block). */
unsigned abbe_thermal_n_inputs(const abbe_thermal_model_t *thermal);
unsigned abbe_thermal_n_channels(const abbe_thermal_model_t *thermal);

/* The compensator's cycle (abbe_comp_step_f32 / _q, abbe/comp.h) with the
 * thermal error added to the model's before the safety layer (limits, rate,
 * fades). thermal may be NULL (then exactly abbe_comp_step_*); its apply()
 * runs every cycle, so thermal's period is the compensator's cycle. The
 * plain steps stay as they were: a firmware without a thermal block pays
 * nothing for this one. */
abbe_status_t abbe_comp_step_thermal_f32(abbe_comp_t *comp, abbe_thermal_state_t *thermal,
                                         const abbe_comp_input_f32_t *in, abbe_comp_output_t *out);
abbe_status_t abbe_comp_step_thermal_q(abbe_comp_t *comp, abbe_thermal_state_t *thermal,
                                       const abbe_comp_input_q_t *in, abbe_comp_output_t *out);

/* The compensator's cycle with the thermal part advanced by elapsed_ms
 * (abbe_thermal_apply_ms_*) instead of one period. */
abbe_status_t abbe_comp_step_thermal_ms_f32(abbe_comp_t *comp, abbe_thermal_state_t *thermal, uint32_t elapsed_ms,
                                            const abbe_comp_input_f32_t *in, abbe_comp_output_t *out);
abbe_status_t abbe_comp_step_thermal_ms_q(abbe_comp_t *comp, abbe_thermal_state_t *thermal, uint32_t elapsed_ms,
                                          const abbe_comp_input_q_t *in, abbe_comp_output_t *out);

size_t abbe_thermal_model_sizeof(void);
size_t abbe_thermal_state_sizeof(void);

#ifdef __cplusplus
} /* extern "C" */
#endif

#endif /* ABBE_THERMAL_H */
