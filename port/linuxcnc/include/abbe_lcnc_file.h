/* abbe LinuxCNC port: read a table file at component load time (uspace only;
 * never from the realtime function). */
#ifndef ABBE_LCNC_FILE_H
#define ABBE_LCNC_FILE_H

#include <stddef.h>

/* Read the whole file at path into buf[0 .. capacity). On success returns 0
 * and sets *size. On failure returns -1 and writes a one-line reason (no
 * newline) into why: "cannot open: <strerror>", "empty file", "larger than
 * N bytes", "read error: <strerror>". */
int abbe_lcnc_read_file(const char *path, void *buf, size_t capacity, size_t *size,
                        char *why, size_t why_size);

#endif /* ABBE_LCNC_FILE_H */
