/* abbe CAN port: the configuration file (docs/can.md "Configuration").
 *
 * The file is a small subset of TOML (so tomllib reads it too): comments,
 * [section] headers, key = value with integers (decimal or 0x hex), decimals,
 * true/false and "strings". Unknown sections and keys, duplicates, values of
 * the wrong type or out of range are errors that name the file, the line and
 * the field. Parsing uses no heap (a line buffer on the stack).
 */
#ifndef ABBE_CAN_CONFIG_H
#define ABBE_CAN_CONFIG_H

#include <stddef.h>

#include "abbe_can.h"

#define ABBE_CAN_LINE_MAX 512u      /* longest line */
#define ABBE_CAN_CONFIG_MAX 32768u  /* largest file */

/* Where and why a configuration was refused. line 0: no line applies (the
 * file could not be read). field: dotted name as in the file ("axis.X.sign"),
 * empty if none. */
typedef struct {
    char file[ABBE_CAN_PATH_MAX];
    unsigned line;
    char field[64];
    char message[192];
} abbe_can_config_error_t;

/* Parse text[0 .. len) named name (used in messages and to resolve a relative
 * model path against its directory), starting from abbe_can_config_defaults()
 * and ending with abbe_can_config_check(). Returns ABBE_CAN_OK or
 * ABBE_CAN_E_CONFIG with *err filled; *cfg is then unspecified. */
int abbe_can_config_parse(abbe_can_config_t *cfg, const char *text, size_t len, const char *name,
                          abbe_can_config_error_t *err);

/* Read and parse the file at path (ABBE_CAN_E_CONFIG also for an unreadable
 * or oversized file, line 0). */
int abbe_can_config_load(abbe_can_config_t *cfg, const char *path, abbe_can_config_error_t *err);

/* "FILE:LINE: field 'F': MESSAGE" (the abbe CLI's format; ":LINE" and the
 * field part are left out when they do not apply). Returns what snprintf does. */
int abbe_can_config_error_format(const abbe_can_config_error_t *err, char *buf, size_t size);

#endif /* ABBE_CAN_CONFIG_H */
