/* abbe LinuxCNC port: table file reader (load time only). */
#include <errno.h>
#include <stdio.h>
#include <string.h>

#include "abbe_lcnc_file.h"

int abbe_lcnc_read_file(const char *path, void *buf, size_t capacity, size_t *size,
                        char *why, size_t why_size)
{
    if (path == NULL || buf == NULL || size == NULL || why == NULL || why_size == 0u) {
        return -1;
    }
    why[0] = '\0';
    FILE *f = fopen(path, "rb");
    if (f == NULL) {
        (void)snprintf(why, why_size, "cannot open: %s", strerror(errno));
        return -1;
    }
    /* One byte more than the capacity tells "too large" from "exactly full". */
    size_t got = 0;
    unsigned char extra;
    int rc = 0;
    got = fread(buf, 1, capacity, f);
    if (ferror(f)) {
        (void)snprintf(why, why_size, "read error: %s", strerror(errno));
        rc = -1;
    } else if (got == capacity && fread(&extra, 1, 1, f) == 1u) {
        (void)snprintf(why, why_size, "larger than %zu bytes", capacity);
        rc = -1;
    } else if (got == 0u) {
        (void)snprintf(why, why_size, "empty file");
        rc = -1;
    }
    (void)fclose(f);
    if (rc == 0) {
        *size = got;
    }
    return rc;
}
