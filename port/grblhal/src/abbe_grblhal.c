/* abbe grblHAL plugin: installs the compensation on grblHAL's kinematics
 * interface, adds its $ settings, the $ABBE / $ABBEU / $ABBET / $ABBERESET
 * commands and the |ABBE: field of the status report (docs/grblhal.md).
 *
 * The plugin is Apache-2.0 (the project's licence); it includes grblHAL's
 * headers, and a firmware image that links grblHAL is GPL-3.0-or-later.
 * Everything that does not need grblHAL is in the core (abbe_grblhal_core*.c).
 * The glue is this file (init, the kinematics, messages, the status report),
 * abbe_grblhal_store.c, abbe_grblhal_settings.c and abbe_grblhal_commands.c
 * (abbe_grblhal_glue.h). */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "grbl/hal.h"
#include "grbl/kinematics/interface.h"
#include "grbl/machine_limits.h"
#include "grbl/planner.h"
#include "grbl/report.h"
#include "grbl/settings.h"
#include "grbl/state_machine.h"
#include "grbl/system.h"

#include "abbe_grblhal.h"
#include "abbe_grblhal_glue.h"

#ifndef KINEMATICS_API
#error "abbe_grblhal needs grblHAL built with KINEMATICS_API defined"
#endif
#if N_AXIS < 3
#error "abbe_grblhal compensates X, Y and Z"
#endif

abbe_gh_t abbe_plugin;

/* segment_line state: mc_line() keeps the pointer the first call returns and
 * hands it to the planner after every later call, so every segment is written
 * into seg_buf. */
static coord_data_t seg_buf, final_target;
static abbe_gh_line_t line;
static uint32_t segments_left;
static bool line_compensated;
static volatile bool jog_cancel;
static float last_motor[3];
static bool have_last_motor;

/* Messages wait for the foreground (on_execute_realtime). */
static char pending_msg[ABBE_PLUGIN_MESSAGE_BYTES];
static volatile bool msg_pending;
static bool msg_warning;
static bool fault_reported;

static on_report_options_ptr on_report_options;
static on_realtime_report_ptr on_realtime_report;
static on_execute_realtime_ptr on_execute_realtime;
static on_jog_cancel_ptr on_jog_cancel;
static on_state_change_ptr on_state_change;
static travel_limits_ptr check_travel_limits;

void abbe_plugin_queue_message(const char *text, bool warning)
{
    msg_warning = warning;
    strncpy(pending_msg, text, sizeof pending_msg - 1u);
    pending_msg[sizeof pending_msg - 1u] = '\0';
    msg_pending = true;
}

void abbe_plugin_rearm_fault_message(void)
{
    fault_reported = false;
}

/* ---- kinematics ---------------------------------------------------------- */

/* Cartesian (programmed) position -> motor position: p - E(p), one
 * compensator step per call (a segment end). Homing moves (the only other
 * caller in grblHAL's core) go through unchanged. */
static coord_data_t *abbe_transform_from_cartesian(coord_data_t *target, coord_data_t *position)
{
    uint_fast8_t idx;
    for (idx = 0; idx < N_AXIS; idx++)
        target->values[idx] = position->values[idx];

    if (state_get() != STATE_HOMING && abbe_gh_active(&abbe_plugin)) {
        float motor[3];
        abbe_gh_clock(&abbe_plugin, hal.get_elapsed_ticks()); /* the thermal block advances by real time */
        uint32_t flags = abbe_gh_forward(&abbe_plugin, position->values, motor);
        for (idx = 0; idx < 3; idx++)
            target->values[idx] = motor[idx];
        if ((flags & ABBE_FLAG_LIMIT) && !fault_reported) {
            fault_reported = true;
            abbe_plugin_queue_message("abbe: correction limit exceeded, compensation fades out ($ABBERESET clears)", true);
        }
        if (flags & ABBE_FLAG_MODEL_SWAPPED) {
            char text[64];
            snprintf(text, sizeof text, "abbe: table %08lX in use", (unsigned long)abbe_model_crc(abbe_gh_model(&abbe_plugin)));
            abbe_plugin_queue_message(text, false);
        }
    }
    return target;
}

/* Motor steps -> Cartesian position: the inverse (bounded fixed point). */
static coord_data_t *abbe_steps_to_cartesian(coord_data_t *position, mpos_t *steps)
{
    uint_fast8_t idx;
    float motor[3], cart[3];
    for (idx = 0; idx < N_AXIS; idx++)
        position->values[idx] = (float)steps->values[idx] / settings.axis[idx].steps_per_mm;
    for (idx = 0; idx < 3; idx++)
        motor[idx] = position->values[idx];
    (void)abbe_gh_inverse(&abbe_plugin, motor, cart);
    for (idx = 0; idx < 3; idx++)
        position->values[idx] = cart[idx];
    return position;
}

/* Where the line starts, Cartesian: the last segment end if the planner is
 * still there, else (after homing, a reset, a position change) the inverse of
 * the planner's position. */
static void line_start(const coord_data_t *position, float start[3])
{
    bool same = have_last_motor;
    uint_fast8_t idx;
    for (idx = 0; idx < 3 && same; idx++)
        same = fabsf(position->values[idx] - last_motor[idx]) <= 0.5f / settings.axis[idx].steps_per_mm + 1e-6f;
    if (same) {
        memcpy(start, abbe_plugin.last_cart, sizeof(float) * 3);
    } else {
        float motor[3] = {position->values[0], position->values[1], position->values[2]};
        (void)abbe_gh_inverse(&abbe_plugin, motor, start);
        abbe_gh_set_position(&abbe_plugin, start);
    }
}

static coord_data_t *abbe_segment_line(coord_data_t *target, coord_data_t *position, plan_line_data_t *pl_data,
                                       bool init)
{
    (void)pl_data;
    if (init) {
        float start[3];
        jog_cancel = false;
        memcpy(&final_target, target, sizeof(coord_data_t));
        line_start(position, start);
        line_compensated = abbe_gh_active(&abbe_plugin);
        if (line_compensated)
            segments_left = abbe_gh_line_begin(&abbe_plugin, &line, start, target->values);
        else {
            segments_left = 1;
            abbe_gh_set_position(&abbe_plugin, target->values);
        }
        /* The first return is checked against the soft limits: the programmed
         * (Cartesian) target, as without the plugin. */
        memcpy(&seg_buf, target, sizeof(coord_data_t));
        return &seg_buf;
    }

    if (jog_cancel || segments_left == 0)
        return NULL;
    segments_left--;

    if (line_compensated) {
        coord_data_t cart;
        memcpy(&cart, &final_target, sizeof(coord_data_t));
        (void)abbe_gh_line_next(&line, cart.values);
        abbe_transform_from_cartesian(&seg_buf, &cart);
    } else
        memcpy(&seg_buf, &final_target, sizeof(coord_data_t));

    memcpy(last_motor, seg_buf.values, sizeof last_motor);
    have_last_motor = true;
    return &seg_buf;
}

/* Limits and homing exactly as grblHAL does them without kinematics. */
static uint_fast8_t abbe_limits_get_axis_mask(uint_fast8_t idx)
{
    return bit(idx);
}

static void abbe_limits_set_target_pos(uint_fast8_t idx)
{
    sys.position[idx] = 0;
}

/* Homing sets the motor positions: the correction restarts from zero there
 * (MPos = grblHAL's own home position) and fades in with the next moves. */
static void rehome(void)
{
    (void)abbe_gh_rehome(&abbe_plugin);
    have_last_motor = false; /* the next line starts at the planner's (homed) position */
}

static void abbe_limits_set_machine_positions(axes_signals_t cycle)
{
    /* The pull-off is added after a homing cycle, not for manual homing. */
    limits_set_machine_positions(cycle, state_get() == STATE_HOMING);
    rehome();
}

/* A homing cycle's moves are raw motor moves (transform_from_cartesian passes
 * them through): from its start the correction is zero, so positions reported
 * during and after it (also when it fails) are grblHAL's own. */
static void abbe_state_change(sys_state_t state)
{
    if (state == STATE_HOMING)
        rehome();
    if (on_state_change)
        on_state_change(state);
}

/* mc_line() checks the first segment_line() return, the Cartesian target. */
static bool abbe_check_travel_limits(float *target, axes_signals_t axes, bool is_cartesian, work_envelope_t *envelope)
{
    (void)is_cartesian;
    return check_travel_limits(target, axes, true, envelope);
}

static void abbe_jog_cancel(sys_state_t state)
{
    jog_cancel = true;
    if (on_jog_cancel)
        on_jog_cancel(state);
}

void abbe_plugin_last_steps(long steps[3])
{
    uint_fast8_t idx;
    for (idx = 0; idx < 3; idx++)
        steps[idx] = have_last_motor ? lroundf(last_motor[idx] * settings.axis[idx].steps_per_mm)
                                     : (long)sys.position[idx];
}

/* ---- reports --------------------------------------------------------------- */

static void abbe_realtime_report(stream_write_ptr stream_write, report_tracking_flags_t report)
{
    char buf[32];
    snprintf(buf, sizeof buf, "|ABBE:%s,%08lX", abbe_plugin_state_name(), (unsigned long)abbe_plugin_table_crc());
    stream_write(buf);
    if (on_realtime_report)
        on_realtime_report(stream_write, report);
}

static void abbe_execute_realtime(sys_state_t state)
{
    if (msg_pending) {
        msg_pending = false;
        report_message(pending_msg, msg_warning ? Message_Warning : Message_Info);
    }
    on_execute_realtime(state);
}

static void abbe_report_options(bool newopt)
{
    on_report_options(newopt);
    if (!newopt)
        hal.stream.write("[PLUGIN:abbe geometric compensation v0.1]" ASCII_EOL);
}

/* ---- init ------------------------------------------------------------------ */

void abbe_grblhal_init(void)
{
    abbe_gh_params_t p;
    abbe_gh_default_params(&p);
    (void)abbe_gh_init(&abbe_plugin, &p, NULL, 0); /* the table is chosen at settings load (boot_table) */
    abbe_plugin_settings_init(&p);

    kinematics.limits_set_target_pos = abbe_limits_set_target_pos;
    kinematics.limits_get_axis_mask = abbe_limits_get_axis_mask;
    kinematics.limits_set_machine_positions = abbe_limits_set_machine_positions;
    kinematics.transform_from_cartesian = abbe_transform_from_cartesian;
    kinematics.transform_steps_to_cartesian = abbe_steps_to_cartesian;
    kinematics.segment_line = abbe_segment_line;
    kinematics.homing_cycle_validate = NULL;
    kinematics.homing_cycle_get_feedrate = NULL;

    check_travel_limits = grbl.check_travel_limits;
    grbl.check_travel_limits = abbe_check_travel_limits;

    on_jog_cancel = grbl.on_jog_cancel;
    grbl.on_jog_cancel = abbe_jog_cancel;

    on_state_change = grbl.on_state_change;
    grbl.on_state_change = abbe_state_change;

    on_realtime_report = grbl.on_realtime_report;
    grbl.on_realtime_report = abbe_realtime_report;

    on_execute_realtime = grbl.on_execute_realtime;
    grbl.on_execute_realtime = abbe_execute_realtime;

    on_report_options = grbl.on_report_options;
    grbl.on_report_options = abbe_report_options;

    abbe_plugin_register_commands();
}
