/* Helpers shared by the CAN port tests (test code only). */
#ifndef ABBE_CAN_TEST_UTIL_H
#define ABBE_CAN_TEST_UTIL_H

#include <stddef.h>
#include <stdint.h>

#include "abbe_can.h"

#define CTU_EXAMPLE_MODEL ABBE_CAN_REPO "/examples/paper_table/model.bin"

/* Whole file into buf (asserts it fits); returns its size. */
size_t ctu_read_file(const char *path, uint8_t *buf, size_t cap);
void ctu_write_file(const char *path, const void *data, size_t size);
/* A fresh directory under $TMPDIR (or /tmp); path gets its name. */
void ctu_tmpdir(char *path, size_t size);
/* Remove dir and the files named in it (flat). */
void ctu_rmtree(const char *dir);
/* Recompute the CRC-32 of a table blob after a change (total_size from the header). */
void ctu_fix_crc(uint8_t *blob);
/* Little-endian int32 field of a blob. */
void ctu_put_i32(uint8_t *p, int32_t v);
int32_t ctu_get_i32(const uint8_t *p);

abbe_can_frame_t ctu_frame(uint32_t id, uint8_t dlc, const uint8_t *data);
/* A frame of dlc zero bytes with an INT32 at byte. */
abbe_can_frame_t ctu_i32_frame(uint32_t id, uint8_t dlc, unsigned byte, int32_t v);

#endif
