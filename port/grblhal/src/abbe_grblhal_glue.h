/* abbe grblHAL plugin glue, private: what its files share. The glue is the
 * part that needs grblHAL (docs/grblhal.md): abbe_grblhal.c (init, the
 * kinematics, messages and the status report), abbe_grblhal_store.c (the
 * uploaded table in non-volatile storage, the table chosen at start-up),
 * abbe_grblhal_settings.c (the $ settings) and abbe_grblhal_commands.c ($ABBE,
 * $ABBEU, $ABBET, $ABBERESET). Everything here is abbe_plugin_*: the glue
 * links into grblHAL's firmware, one namespace with grblHAL's own names. */
#ifndef ABBE_GRBLHAL_GLUE_H
#define ABBE_GRBLHAL_GLUE_H

#include <stdbool.h>
#include <stdint.h>

#include "abbe_grblhal_core.h"

/* The plugin core's state (abbe_grblhal.c): one per firmware. */
extern abbe_gh_t abbe_plugin;

/* ---- abbe_grblhal.c ---- */

/* Longest message queued for the foreground, bytes with the NUL. */
#define ABBE_PLUGIN_MESSAGE_BYTES 176u

/* Queue a message for the foreground (on_execute_realtime sends it); a later
 * one replaces one not sent yet. */
void abbe_plugin_queue_message(const char *text, bool warning);

/* The limit fault is reported once; $ABBERESET re-arms the report. */
void abbe_plugin_rearm_fault_message(void);

/* The planner's target of the last segment end, steps (rounded as
 * plan_buffer_line() does), or the machine's position before any. */
void abbe_plugin_last_steps(long steps[3]);

/* ---- abbe_grblhal_store.c ---- */

/* Largest blob the storage holds, bytes (0: no storage for tables). */
uint32_t abbe_plugin_store_capacity(void);

/* Keep the blob just committed for the next start-up: invalidate the header,
 * write the blob, write the header, read it all back. Returns false with *why. */
bool abbe_plugin_store_table(const uint8_t *blob, uint32_t size, uint32_t crc, const char **why);

/* Invalidate the stored table's header (nothing stored: nothing done). */
void abbe_plugin_store_erase(void);

/* Choose the table to run from start-up (a valid stored one if try_stored,
 * else the compiled-in one, else none) and start the core with it. */
void abbe_plugin_boot_table(const abbe_gh_params_t *p, bool try_stored);

/* What the start-up chose, as $ABBE reports it; the compiled-in table's
 * refusal (ABBE_OK: none). */
const char *abbe_plugin_boot_text(void);
abbe_status_t abbe_plugin_boot_status(void);

/* ---- abbe_grblhal_settings.c ---- */

/* Register the $ settings (the table is then chosen when grblHAL loads its
 * settings); without a settings area, choose the compiled-in table and enable
 * with the defaults p. */
void abbe_plugin_settings_init(const abbe_gh_params_t *p);

/* The enable setting ($450). */
bool abbe_plugin_enable_setting(void);

/* ---- abbe_grblhal_commands.c ---- */

/* The state the status report and $ABBE show: NOTABLE, ON, FADE, FAULT, OFF. */
const char *abbe_plugin_state_name(void);

/* CRC-32 of the running (or queued) table, 0: none. */
uint32_t abbe_plugin_table_crc(void);

/* Register $ABBE, $ABBEU, $ABBET and $ABBERESET. */
void abbe_plugin_register_commands(void);

#endif /* ABBE_GRBLHAL_GLUE_H */
