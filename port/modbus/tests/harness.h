/* Test and benchmark harness for abbe-modbusd: start the server with a ready
 * signal (a pipe, port chosen at run time), stop it by pid; libmodbus client
 * helpers for the register map (word order, upload). Test code only. */
#ifndef ABBE_MODBUS_HARNESS_H
#define ABBE_MODBUS_HARNESS_H

#include <stddef.h>
#include <stdint.h>
#include <sys/types.h>

#include <modbus.h>

typedef struct {
    pid_t pid;
    int port; /* TCP port from the ready line, -1 for RTU */
} mbt_server_t;

/* Start argv[0] (argv NULL-terminated) with "--ready-fd N" appended, wait up to
 * timeout_ms for its "ready ..." line. prefix (NULL-terminated, may be NULL) is
 * put in front, e.g. {"valgrind", "--error-exitcode=99", NULL}.
 * Returns 0, or -1 (server died or did not get ready: it is then killed). */
int mbt_server_start(mbt_server_t *s, const char *const *prefix, const char *const *argv,
                     int timeout_ms);

/* SIGTERM, then wait. Returns the exit status, or 128 + signal if killed by one. */
int mbt_server_stop(mbt_server_t *s);

/* Read a whole file (at most cap bytes). Returns its size or -1. */
long mbt_read_file(const char *path, uint8_t *buf, size_t cap);

/* 32-bit values in two registers, in word order wo (ABBE_MB_WORD_ORDER_*). */
void mbt_put32(uint16_t *dst, uint32_t v, int wo);
uint32_t mbt_get32(const uint16_t *src, int wo);

/* Read / write one 32-bit register pair (word order wo). 0 or -1 + errno. */
int mbt_read32(modbus_t *ctx, int addr, int wo, uint32_t *v);

/* Upload: begin, write blob in chunks of chunk_regs registers (pads an odd
 * length), commit (len, crc). Returns 0 or -1 with errno from the failing
 * request (EMBX* for a Modbus exception). */
int mbt_upload(modbus_t *ctx, const uint8_t *blob, size_t len, uint32_t crc, int chunk_regs, int wo);

/* Begin an upload session (UP_CMD = BEGIN). */
int mbt_upload_begin(modbus_t *ctx);

/* Write bytes [off, off + len) of blob into the staging area (off, len even
 * except a final odd byte, which is padded). */
int mbt_upload_chunk(modbus_t *ctx, const uint8_t *blob, size_t off, size_t len);

/* Write the commit registers. */
int mbt_upload_commit(modbus_t *ctx, uint32_t len, uint32_t crc, int wo);

/* Send a raw request (PDU without header; the function adds unit 1 and the
 * checksum) and return the exception code of the reply (0: normal reply). */
int mbt_raw_exception(modbus_t *ctx, const uint8_t *pdu, int pdu_len);

/* TCP client connected to 127.0.0.1:port with a 5 s response timeout. */
modbus_t *mbt_tcp_client(int port);

#endif /* ABBE_MODBUS_HARNESS_H */
