/* Helpers shared by the CAN port tests. */
#define _POSIX_C_SOURCE 200809L

#include <dirent.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <cmocka.h>

#include "can_test_util.h"

size_t ctu_read_file(const char *path, uint8_t *buf, size_t cap)
{
    FILE *fp = fopen(path, "rb");
    assert_non_null(fp);
    size_t n = fread(buf, 1, cap, fp);
    assert_true(n < cap);
    fclose(fp);
    return n;
}

void ctu_write_file(const char *path, const void *data, size_t size)
{
    FILE *fp = fopen(path, "wb");
    assert_non_null(fp);
    assert_int_equal(fwrite(data, 1, size, fp), size);
    assert_int_equal(fclose(fp), 0);
}

void ctu_tmpdir(char *path, size_t size)
{
    const char *base = getenv("TMPDIR");
    snprintf(path, size, "%s/abbe-can-test-XXXXXX", base != NULL && base[0] != '\0' ? base : "/tmp");
    assert_non_null(mkdtemp(path));
}

void ctu_rmtree(const char *dir)
{
    DIR *d = opendir(dir);
    if (d == NULL) {
        return;
    }
    struct dirent *e;
    while ((e = readdir(d)) != NULL) {
        if (strcmp(e->d_name, ".") == 0 || strcmp(e->d_name, "..") == 0) {
            continue;
        }
        char p[1024];
        snprintf(p, sizeof p, "%s/%s", dir, e->d_name);
        unlink(p);
    }
    closedir(d);
    rmdir(dir);
}

void ctu_put_i32(uint8_t *p, int32_t v)
{
    abbe_can_put_i32(p, v);
}

int32_t ctu_get_i32(const uint8_t *p)
{
    return abbe_can_get_i32(p);
}

void ctu_fix_crc(uint8_t *blob)
{
    uint32_t total = abbe_can_get_u32(blob + 8);
    abbe_can_put_u32(blob + total - 4u, abbe_crc32(0, blob, total - 4u));
}

abbe_can_frame_t ctu_frame(uint32_t id, uint8_t dlc, const uint8_t *data)
{
    abbe_can_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = id;
    f.dlc = dlc;
    if (data != NULL) {
        memcpy(f.data, data, dlc > 8 ? 8 : dlc);
    }
    return f;
}

abbe_can_frame_t ctu_i32_frame(uint32_t id, uint8_t dlc, unsigned byte, int32_t v)
{
    abbe_can_frame_t f = ctu_frame(id, dlc, NULL);
    abbe_can_put_i32(&f.data[byte], v);
    return f;
}
