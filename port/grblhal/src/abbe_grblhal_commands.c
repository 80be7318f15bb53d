/* abbe grblHAL plugin glue: the commands (docs/grblhal.md): $ABBE (state,
 * table, segmentation, start-up, temperatures), $ABBEU (table upload: the
 * core checks it, abbe_grblhal_store.c keeps it), $ABBET (temperature
 * samples of the table's thermal block) and $ABBERESET (clear a fault). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "grbl/hal.h"
#include "grbl/protocol.h"
#include "grbl/report.h"
#include "grbl/state_machine.h"
#include "grbl/system.h"

#include "abbe_grblhal_glue.h"

const char *abbe_plugin_state_name(void)
{
    if (abbe_gh_model(&abbe_plugin) == NULL && abbe_plugin.running == 0xFF)
        return "NOTABLE";
    switch (abbe_gh_state(&abbe_plugin)) {
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

uint32_t abbe_plugin_table_crc(void)
{
    const abbe_model_t *m = abbe_gh_model(&abbe_plugin);
    if (m == NULL && abbe_plugin.running != 0xFF)
        m = &abbe_plugin.slot[abbe_plugin.running].model;
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
    const abbe_thermal_state_t *st = abbe_gh_thermal(&abbe_plugin);
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
    long age = abbe_plugin.thermal_sampled ? (long)(hal.get_elapsed_ticks() - abbe_plugin.thermal_sample_ms) : -1L;
    snprintf(buf, size,
             "[ABBE:THERMAL:%u inputs,%u channels|FLAGS:%02lX|EVENTS:%02lX|FAULTS:%05lX|OUT:%.3f,%.3f,%.3f um|AGE:%ld ms"
             "|APPLIED:%lu ms]"
             ASCII_EOL,
             abbe_thermal_n_inputs(st->model), abbe_thermal_n_channels(st->model),
             (unsigned long)abbe_thermal_flags(st), (unsigned long)abbe_thermal_events(st),
             (unsigned long)abbe_thermal_input_faults(st), (double)out[0], (double)out[1], (double)out[2], age,
             (unsigned long)abbe_plugin.thermal_apply_ms);
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
    const abbe_thermal_state_t *st = abbe_gh_thermal(&abbe_plugin);
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
    abbe_gh_clock(&abbe_plugin, hal.get_elapsed_ticks());
    if (abbe_gh_thermal_sample(&abbe_plugin, x, valid, &why) != ABBE_OK)
        return thermal_fail(why);
    return Status_OK;
}

/* $ABBE: state, table, segmentation. */
static status_code_t cmd_info(sys_state_t state, char *args)
{
    (void)state;
    (void)args;
    char buf[224];
    float kappa = abbe_plugin.running != 0xFF ? abbe_plugin.slot[abbe_plugin.running].kappa_um_per_mm2 : 0.0f;
    /* STEPS: the planner's target of the last segment end, steps (rounded as
     * plan_buffer_line() does): where the motors stop, unless the stepper lost
     * a step (a sender or a test compares it with the machine's counts). */
    long steps[3];
    abbe_plugin_last_steps(steps);
    snprintf(buf, sizeof buf,
             "[ABBE:%s|TABLE:%08lX|CURV:%.4f um/mm2|SEG:%.3f mm|DEV:%.3f um|SEGMENTS:%lu|FLAGS:%04lX|STEPS:%ld,%ld,%ld]"
             ASCII_EOL,
             abbe_plugin_state_name(), (unsigned long)abbe_plugin_table_crc(), (double)kappa, (double)abbe_plugin.seg_len_mm,
             (double)abbe_gh_deviation_um(abbe_plugin.seg_len_mm, kappa), (unsigned long)abbe_plugin.segments,
             (unsigned long)abbe_plugin.flags, steps[0], steps[1], steps[2]);
    hal.stream.write(buf);
    if (abbe_plugin_boot_status() != ABBE_OK) {
        snprintf(buf, sizeof buf, "[ABBE:compiled-in table refused: %s]" ASCII_EOL, abbe_strerror(abbe_plugin_boot_status()));
        hal.stream.write(buf);
    }
    snprintf(buf, sizeof buf, "[ABBE:start-up: %s|STORE:%lu bytes]" ASCII_EOL, abbe_plugin_boot_text(),
             (unsigned long)abbe_plugin_store_capacity());
    hal.stream.write(buf);
    thermal_info(buf, sizeof buf);
    hal.stream.write(buf);
    return Status_OK;
}

static status_code_t cmd_reset(sys_state_t state, char *args)
{
    (void)state;
    (void)args;
    (void)abbe_gh_set_enabled(&abbe_plugin, 2);
    abbe_plugin_rearm_fault_message();
    if (abbe_plugin_enable_setting())
        (void)abbe_gh_set_enabled(&abbe_plugin, 1);
    return Status_OK;
}

static int hex_nibble(char c)
{
    if (c >= '0' && c <= '9')
        return c - '0';
    if (c >= 'A' && c <= 'F')
        return c - 'A' + 10;
    if (c >= 'a' && c <= 'f')
        return c - 'a' + 10;
    return -1;
}

/* Unsigned decimal (base 10) or hex (base 16) field ending at ',' or '\0'. */
static bool parse_u32(char **s, unsigned base, uint32_t *out)
{
    uint64_t v = 0;
    char *p = *s;
    int d;
    if (*p == '\0' || *p == ',')
        return false;
    while (*p && *p != ',') {
        d = hex_nibble(*p);
        if (d < 0 || (unsigned)d >= base)
            return false;
        v = v * base + (unsigned)d;
        if (v > 0xFFFFFFFFu)
            return false;
        p++;
    }
    if (*p == ',')
        p++;
    *s = p;
    *out = (uint32_t)v;
    return true;
}

static status_code_t upload_fail(const char *why)
{
    char text[160];
    snprintf(text, sizeof text, "abbe upload refused: %s; the running table stays", why);
    report_message(text, Message_Warning);
    return Status_InvalidStatement;
}

/* $ABBEU=B,<size>,<crc32 hex> | D,<offset>,<hex bytes> | C | A | E (docs/grblhal.md). */
static status_code_t cmd_upload(sys_state_t state, char *args)
{
    const char *why = "";
    uint32_t a, b;
    if (args == NULL || args[0] == '\0' || (args[1] != ',' && args[1] != '\0'))
        return upload_fail("expected B,<size>,<crc32>  D,<offset>,<hex>  C  A  or E");
    char op = args[0];
    char *p = args[1] == ',' ? args + 2 : args + 1;
    switch (op) {
    case 'B':
    case 'b':
        if (!parse_u32(&p, 10, &a) || !parse_u32(&p, 16, &b) || *p != '\0')
            return upload_fail("B needs <size in bytes, decimal>,<CRC-32, hex>");
        if (abbe_gh_upload_begin(&abbe_plugin, a, b, &why) != ABBE_OK)
            return upload_fail(why);
        return Status_OK;
    case 'D':
    case 'd': {
        uint8_t bytes[(LINE_BUFFER_SIZE) / 2];
        uint32_t n = 0;
        if (!parse_u32(&p, 10, &a))
            return upload_fail("D needs <offset, decimal>,<data, hex>");
        while (p[0] && p[1]) {
            int hi = hex_nibble(p[0]), lo = hex_nibble(p[1]);
            if (hi < 0 || lo < 0 || n >= sizeof bytes) {
                abbe_gh_upload_abort(&abbe_plugin);
                return upload_fail("data is not hex; upload aborted");
            }
            bytes[n++] = (uint8_t)(hi * 16 + lo);
            p += 2;
        }
        if (*p != '\0' || n == 0) {
            abbe_gh_upload_abort(&abbe_plugin);
            return upload_fail("data needs an even number (> 0) of hex digits; upload aborted");
        }
        if (abbe_gh_upload_data(&abbe_plugin, a, bytes, n, &why) != ABBE_OK) {
            abbe_gh_upload_abort(&abbe_plugin);
            return upload_fail(why);
        }
        return Status_OK;
    }
    case 'C':
    case 'c':
        if (!(state == STATE_IDLE || state == STATE_ALARM || state == STATE_CHECK_MODE)) {
            abbe_gh_upload_abort(&abbe_plugin);
            return upload_fail("commit only when idle (the table is checked for ~0.1 s)");
        }
        if (abbe_gh_upload_commit(&abbe_plugin, &why) != ABBE_OK)
            return upload_fail(why);
        report_message("abbe upload: table valid, in use from the next segment", Message_Info);
        {
            /* the committed blob is in the staging slot (it is the queued one now) */
            char text[160];
            const uint8_t *blob = (const uint8_t *)abbe_plugin.slot[abbe_plugin.stage.slot].blob;
            if (abbe_plugin_store_table(blob, abbe_plugin.stage.size, abbe_plugin.stage.crc, &why))
                report_message("abbe upload: table stored, in use after a restart", Message_Info);
            else {
                snprintf(text, sizeof text, "abbe upload: table not stored (%s); it runs until a restart", why);
                report_message(text, Message_Warning);
            }
        }
        return Status_OK;
    case 'E':
    case 'e':
        if (*p != '\0')
            return upload_fail("E takes no arguments");
        abbe_plugin_store_erase();
        report_message("abbe: stored table erased, the compiled-in table runs after a restart", Message_Info);
        return Status_OK;
    case 'A':
    case 'a':
        abbe_gh_upload_abort(&abbe_plugin);
        return Status_OK;
    default:
        return upload_fail("unknown operation (B, D, C, A or E)");
    }
}

void abbe_plugin_register_commands(void)
{
    static const sys_command_t command_list[] = {
        {"ABBE", cmd_info, {.noargs = On, .allow_blocking = On}, {.str = "abbe compensation state and table"}},
        {"ABBEU", cmd_upload, {.allow_blocking = Off}, {.str = "abbe table upload: B,size,crc | D,offset,hex | C | A | E (erase stored)"}},
        {"ABBET", cmd_thermal, {.allow_blocking = On}, {.str = "abbe temperatures: v0,v1,... (deg C, rpm; '-' no reading) | CLEAR"}},
        {"ABBERESET", cmd_reset, {.noargs = On}, {.str = "abbe: clear a fault, fade in again if enabled"}},
    };
    static sys_commands_t commands = {
        .n_commands = sizeof(command_list) / sizeof(sys_command_t),
        .commands = command_list,
    };

    system_register_commands(&commands);
}
