/* abbe CAN port: candump -l log lines (the can-utils format), for replay.
 *
 *   (1700000000.123456) can0 123#DEADBEEF
 *   (1700000000.123456) can0 12345678#00      29-bit id (8 hex digits)
 *   (1700000000.123456) can0 123#R            remote request (optionally #R<len>)
 *   (1700000000.123456) can0 20000080#...     error frame (CAN_ERR_FLAG in the id)
 *
 * Pure string functions, no I/O.
 */
#ifndef ABBE_CAN_LOG_H
#define ABBE_CAN_LOG_H

#include <stddef.h>
#include <stdint.h>

#include "abbe_can.h"

typedef struct {
    uint64_t sec;
    uint32_t usec;
    char ifname[ABBE_CAN_IFNAME_MAX];
    abbe_can_frame_t frame;
} abbe_can_log_entry_t;

/* Parse one line (a trailing newline and a trailing direction flag " R"/" T"
 * are accepted). Returns ABBE_CAN_OK, ABBE_CAN_E_UNSUPPORTED for a CAN FD
 * line ("##"), ABBE_CAN_E_PARSE otherwise (*entry unspecified). */
int abbe_can_log_parse(const char *line, abbe_can_log_entry_t *entry);

/* Format as candump -l does, with a trailing newline. Returns the length
 * written (excluding the NUL), or ABBE_CAN_E_ARG if it does not fit. */
int abbe_can_log_format(const abbe_can_log_entry_t *entry, char *buf, size_t size);

#endif /* ABBE_CAN_LOG_H */
