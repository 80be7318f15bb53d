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
<<<<<<< HEAD
    nvs_io_t *io = nvs_buffer_get_physical();
    return io != NULL && io->type != NVS_Flash && io->type != NVS_None && io->memcpy_to_nvs != NULL &&
                   io->memcpy_from_nvs != NULL
               ? io
               : NULL;
}

static uint32_t store_address(void)
{
    uint32_t buffered = NVS_SIZE;
    if (hal.nvs.size_max > NVS_SIZE)
        buffered = hal.nvs.size_max < NVS_SIZE_MAX ? hal.nvs.size_max : NVS_SIZE_MAX;
    return (buffered + 3u) & ~3u;
}

/* Largest blob the storage holds, bytes (0: no storage for tables). */
static uint32_t store_capacity(void)
{
    uint32_t physical = hal.nvs.size_max ? hal.nvs.size_max : (uint32_t)(ABBE_GRBLHAL_NVS_BYTES);
    uint32_t at = store_address() + ABBE_GH_STORE_HEADER_BYTES;
    if (store_io() == NULL || physical <= at)
        return 0u;
    return physical - at;
}

/* CRC-32 of n bytes of storage from addr, read in small pieces. */
static uint32_t store_crc(nvs_io_t *io, uint32_t addr, uint32_t n)
{
    uint8_t buf[64];
    uint32_t crc = 0u;
    while (n > 0u) {
        uint32_t k = n < sizeof buf ? n : (uint32_t)sizeof buf;
        (void)io->memcpy_from_nvs(buf, addr, k, false);
        crc = abbe_crc32(crc, buf, k);
        addr += k;
        n -= k;
    }
    return crc;
}

/* Keep the blob just committed for the next start-up: invalidate the header,
 * write the blob, write the header, read it all back. Returns false with *why. */
static bool store_table(const uint8_t *blob, uint32_t size, uint32_t crc, const char **why)
{
    nvs_io_t *io = store_io();
    uint32_t cap = store_capacity(), at = store_address();
    uint8_t header[ABBE_GH_STORE_HEADER_BYTES];
    static char text[96];
    if (cap == 0u) {
        *why = "this build has no non-volatile storage for tables (ABBE_GRBLHAL_NVS_BYTES)";
        return false;
    }
    if (size > cap) {
        snprintf(text, sizeof text, "%lu bytes, the table storage holds %lu", (unsigned long)size,
                 (unsigned long)cap);
        *why = text;
        return false;
    }
    memset(header, 0, sizeof header);
    (void)io->memcpy_to_nvs(at, header, sizeof header, false);
    (void)io->memcpy_to_nvs(at + ABBE_GH_STORE_HEADER_BYTES, (uint8_t *)blob, size, false);
    abbe_gh_store_header(header, size, crc);
    (void)io->memcpy_to_nvs(at, header, sizeof header, false);
    uint8_t back[ABBE_GH_STORE_HEADER_BYTES];
    (void)io->memcpy_from_nvs(back, at, sizeof back, false);
    if (memcmp(back, header, sizeof header) != 0 || store_crc(io, at + ABBE_GH_STORE_HEADER_BYTES, size) != crc) {
        *why = "read-back differs from what was written";
        return false;
    }
    return true;
}

static void store_erase(void)
{
    nvs_io_t *io = store_io();
    uint8_t header[ABBE_GH_STORE_HEADER_BYTES];
    if (store_capacity() == 0u)
        return;
    memset(header, 0, sizeof header);
    (void)io->memcpy_to_nvs(store_address(), header, sizeof header, false);
}

/* The table to run from start-up: a stored one whose header, CRC-32 and
 * library validation pass; else the compiled-in one; else none. Runs once,
 * before any motion (settings load), so the choice causes no jump. */
static void boot_table(const abbe_gh_params_t *p, bool try_stored)
{
    const char *why = "";
    char stored_why[64] = "";
    uint32_t size = 0, crc = 0;
    if (try_stored && store_capacity() > 0u) {
        nvs_io_t *io = store_io();
        uint8_t header[ABBE_GH_STORE_HEADER_BYTES];
        (void)io->memcpy_from_nvs(header, store_address(), sizeof header, false);
        abbe_gh_store_t st = abbe_gh_store_parse(header, store_capacity(), &size, &crc, &why);
        if (st == ABBE_GH_STORE_VALID) {
            uint8_t *buf = abbe_gh_boot_buffer(&gh);
            (void)io->memcpy_from_nvs(buf, store_address() + ABBE_GH_STORE_HEADER_BYTES, size, false);
            abbe_status_t ls;
            if (abbe_crc32(0u, buf, size) != crc)
                why = "CRC-32 of the stored bytes differs from the header's";
            else if ((ls = abbe_gh_init(&gh, p, buf, size)) != ABBE_OK)
                why = abbe_strerror(ls);
            else {
                snprintf(boot_text, sizeof boot_text, "stored table %08lX (%lu bytes) in use",
                         (unsigned long)abbe_model_crc(abbe_gh_model(&gh)), (unsigned long)size);
                char msg[sizeof pending_msg];
                snprintf(msg, sizeof msg, "abbe: %s", boot_text);
                queue_message(msg, false);
                return;
            }
        }
        if (st != ABBE_GH_STORE_NONE)
            snprintf(stored_why, sizeof stored_why, "%s", why);
    }
#ifdef ABBE_GRBLHAL_BUILTIN
    boot_status = abbe_gh_init(&gh, p, abbe_model_blob, abbe_model_blob_size);
    if (boot_status != ABBE_OK)
        (void)abbe_gh_init(&gh, p, NULL, 0);
#else
    (void)abbe_gh_init(&gh, p, NULL, 0);
#endif
    const abbe_model_t *m = abbe_gh_model(&gh);
    if (stored_why[0]) {
        if (m != NULL)
            snprintf(boot_text, sizeof boot_text, "stored table refused (%s); compiled-in table %08lX in use",
                     stored_why, (unsigned long)abbe_model_crc(m));
        else
            snprintf(boot_text, sizeof boot_text, "stored table refused (%s); no table", stored_why);
        char msg[sizeof pending_msg];
        snprintf(msg, sizeof msg, "abbe: %s", boot_text);
        queue_message(msg, true); /* a stored table was refused */
    } else if (m != NULL)
        snprintf(boot_text, sizeof boot_text, "compiled-in table %08lX in use", (unsigned long)abbe_model_crc(m));
    else
        snprintf(boot_text, sizeof boot_text, "no table");
}

/* ---- settings -------------------------------------------------------------- */

static void apply_settings(void)
{
    abbe_gh_params_t p = gh.params;
    p.max_dev_um = cfg.max_dev_um;
    p.limit_um = cfg.limit_um;
    if (abbe_gh_set_params(&gh, &p) != ABBE_OK)
        queue_message("abbe: settings out of range, the previous ones stay", true);
    if ((cfg.enable != 0) != (gh.enabled != 0))
        (void)abbe_gh_set_enabled(&gh, cfg.enable);
}

static status_code_t set_enable(setting_id_t id, uint_fast16_t value)
{
    (void)id;
    cfg.enable = value ? 1 : 0;
    apply_settings();
    return Status_OK;
}

static uint32_t get_enable(setting_id_t id)
{
    (void)id;
    return cfg.enable;
}

static status_code_t set_float(setting_id_t id, float value)
{
    abbe_nvs_settings_t old = cfg;
    if (id == SETTING_DEVIATION)
        cfg.max_dev_um = value;
    else
        cfg.limit_um = value;
    abbe_gh_params_t p = gh.params;
    p.max_dev_um = cfg.max_dev_um;
    p.limit_um = cfg.limit_um;
    if (abbe_gh_set_params(&gh, &p) != ABBE_OK) {
        cfg = old;
        return Status_SettingValueOutOfRange;
    }
    return Status_OK;
}

static float get_float(setting_id_t id)
{
    return id == SETTING_DEVIATION ? cfg.max_dev_um : cfg.limit_um;
}

static const setting_group_detail_t abbe_groups[] = {
    {Group_Root, Group_Kinematics, "abbe compensation", NULL},
};

static const setting_detail_t abbe_settings[] = {
    {SETTING_ENABLE, Group_Kinematics, "abbe compensation enable", NULL, Format_Bool, NULL, NULL, NULL,
     Setting_NonCoreFn, set_enable, get_enable, NULL, {0}},
    {SETTING_DEVIATION, Group_Kinematics, "abbe segment deviation bound", "um", Format_Decimal, "##0.00", "0.01",
     "100", Setting_NonCoreFn, set_float, get_float, NULL, {0}},
    {SETTING_LIMIT, Group_Kinematics, "abbe maximum correction", "um", Format_Decimal, "###0.0", "1", "2000",
     Setting_NonCoreFn, set_float, get_float, NULL, {0}},
};

static const setting_descr_t abbe_descriptions[] = {
    {SETTING_ENABLE, "Geometric error compensation (abbe table): on / off. Switching fades the correction in or "
                     "out over 32 segments."},
    {SETTING_DEVIATION, "Largest deviation of the correction from the model along a segment, um. Lines are split "
                        "into segments of sqrt(8 x bound / curvature of the table)."},
    {SETTING_LIMIT, "Largest correction per axis, um. Beyond it the compensation faults and fades out."},
};

static void abbe_settings_save(void)
{
    hal.nvs.memcpy_to_nvs(nvs_address, (uint8_t *)&cfg, sizeof cfg, true);
}

static void abbe_settings_restore(void)
{
    abbe_gh_params_t p;
    abbe_gh_default_params(&p);
    cfg.enable = 1;
    cfg.max_dev_um = p.max_dev_um;
    cfg.limit_um = p.limit_um;
    hal.nvs.memcpy_to_nvs(nvs_address, (uint8_t *)&cfg, sizeof cfg, true);
}

static void abbe_settings_load(void)
{
    if (!booted) { /* grblHAL's settings are in RAM now: choose the table */
        abbe_gh_params_t p;
        abbe_gh_default_params(&p);
        boot_table(&p, true);
        booted = true;
    }
    if (hal.nvs.memcpy_from_nvs((uint8_t *)&cfg, nvs_address, sizeof cfg, true) != NVS_TransferResult_OK)
        abbe_settings_restore();
    apply_settings();
}

static setting_details_t setting_details = {
    .groups = abbe_groups,
    .n_groups = sizeof(abbe_groups) / sizeof(setting_group_detail_t),
    .settings = abbe_settings,
    .n_settings = sizeof(abbe_settings) / sizeof(setting_detail_t),
    .descriptions = abbe_descriptions,
    .n_descriptions = sizeof(abbe_descriptions) / sizeof(setting_descr_t),
    .save = abbe_settings_save,
    .load = abbe_settings_load,
    .restore = abbe_settings_restore,
};

/* ---- commands ---------------------------------------------------------------- */

static const char *state_name(void)
{
    if (abbe_gh_model(&gh) == NULL && gh.running == 0xFF)
        return "NOTABLE";
    switch (abbe_gh_state(&gh)) {
    case ABBE_GH_ON:
        return "ON";
    case ABBE_GH_FADING:
        return "FADE";
    case ABBE_GH_FAULT:
        return "FAULT";
    default:
        return "OFF";
    }
}

static uint32_t table_crc(void)
{
    const abbe_model_t *m = abbe_gh_model(&gh);
    if (m == NULL && gh.running != 0xFF)
        m = &gh.slot[gh.running].model;
    return m != NULL ? abbe_model_crc(m) : 0u;
}

/* ---- temperatures ($ABBET, docs/grblhal.md "Temperatures") ---------------- */

/* [ABBE:THERMAL:...]: the running table's thermal block. FLAGS current,
 * EVENTS sticky since the last $ABBET=CLEAR (ABBE_THERMAL_F_*: 01 open,
 * 02 range, 04 step, 08 missing samples, 10 limit, 20 hold, 40 fading, 80 stuck),
 * FAULTS the inputs faulted at the last sample (bit k = input k), OUT the
 * thermal tip error in use (faded), um, AGE ms since the last sample,
 * APPLIED the clock (hal.get_elapsed_ticks(), ms) at the segment end that
 * last applied it. */
static void thermal_info(char *buf, size_t size)
{
    const abbe_thermal_state_t *st = abbe_gh_thermal(&gh);
    if (st == NULL) {
        snprintf(buf, size, "[ABBE:THERMAL:NONE]" ASCII_EOL);
        return;
    }
    float out[3] = {0.0f, 0.0f, 0.0f};
#if ABBE_GH_FIXED_POINT
    for (unsigned j = 0; j < 3u; j++)
        out[j] = (float)st->outq[j] * 1e-3f;
#else
    for (unsigned j = 0; j < 3u; j++)
        out[j] = st->out[j];
#endif
    long age = gh.thermal_sampled ? (long)(hal.get_elapsed_ticks() - gh.thermal_sample_ms) : -1L;
    snprintf(buf, size,
             "[ABBE:THERMAL:%u inputs,%u channels|FLAGS:%02lX|EVENTS:%02lX|FAULTS:%05lX|OUT:%.3f,%.3f,%.3f um|AGE:%ld ms"
             "|APPLIED:%lu ms]"
             ASCII_EOL,
             abbe_thermal_n_inputs(st->model), abbe_thermal_n_channels(st->model),
             (unsigned long)abbe_thermal_flags(st), (unsigned long)abbe_thermal_events(st),
             (unsigned long)abbe_thermal_input_faults(st), (double)out[0], (double)out[1], (double)out[2], age,
             (unsigned long)gh.thermal_apply_ms);
}

static status_code_t thermal_fail(const char *why)
{
    char text[112];
    snprintf(text, sizeof text, "abbe temperatures refused: %s", why);
    report_message(text, Message_Warning);
    return Status_InvalidStatement;
}

/* $ABBET=v0,v1,...: one sample of every input of the table's thermal block,
 * in its order: deg C for temperatures, rpm for the spindle speed; an empty
 * field or '-' is an input without a reading (open circuit). $ABBET=CLEAR
 * clears the sticky events. Sensor faults are answered ok (they are flags). */
static status_code_t cmd_thermal(sys_state_t state, char *args)
{
    (void)state;
    const char *why = "";
    const abbe_thermal_state_t *st = abbe_gh_thermal(&gh);
    if (st == NULL)
        return thermal_fail("the running table has no thermal block");
    if (args == NULL || args[0] == '\0')
        return thermal_fail("expected $ABBET=<v0>,<v1>,... (deg C / rpm per input) or $ABBET=CLEAR");
    if (strcmp(args, "CLEAR") == 0 || strcmp(args, "clear") == 0) {
        abbe_thermal_clear_events((abbe_thermal_state_t *)st);
        return Status_OK;
    }
    unsigned n = abbe_thermal_n_inputs(st->model), k = 0;
    float x[ABBE_THERMAL_MAX_INPUTS];
    uint32_t valid = 0u;
    char *p = args;
    for (;;) {
        if (k >= n)
            return thermal_fail("more values than the thermal block has inputs");
        if (*p == ',' || *p == '\0' || (*p == '-' && (p[1] == ',' || p[1] == '\0'))) {
            x[k] = 0.0f; /* no reading */
            p += *p == '-' ? 1 : 0;
        } else {
            char *end;
            x[k] = strtof(p, &end);
            if (end == p || (*end != ',' && *end != '\0'))
                return thermal_fail("a value is not a number (deg C or rpm, '-' or empty: no reading)");
            valid |= 1u << k;
            p = end;
        }
        k++;
        if (*p == '\0')
            break;
        p++; /* ',' */
    }
    if (k != n) {
        char text[80];
        snprintf(text, sizeof text, "%u values, the thermal block has %u inputs", k, n);
        return thermal_fail(text);
    }
    abbe_gh_clock(&gh, hal.get_elapsed_ticks());
    if (abbe_gh_thermal_sample(&gh, x, valid, &why) != ABBE_OK)
        return thermal_fail(why);
    return Status_OK;
}

/* $ABBE: state, table, segmentation. */
static status_code_t cmd_info(sys_state_t state, char *args)
{
    (void)state;
    (void)args;
    char buf[224];
    float kappa = gh.running != 0xFF ? gh.slot[gh.running].kappa_um_per_mm2 : 0.0f;
    /* STEPS: the planner's target of the last segment end, steps (rounded as
     * plan_buffer_line() does): where the motors stop, unless the stepper lost
     * a step (a sender or a test compares it with the machine's counts). */
    long steps[3];
=======
>>>>>>> h_house_ports
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
