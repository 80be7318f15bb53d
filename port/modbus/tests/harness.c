/* Harness for abbe-modbusd tests and benchmarks (harness.h). */
#define _POSIX_C_SOURCE 200809L

#include "harness.h"

#include <errno.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "abbe/modbus_regs.h"

int mbt_server_start(mbt_server_t *s, const char *const *prefix, const char *const *argv,
                     int timeout_ms)
{
    int p[2];
    char fdarg[16];
    const char *args[64];
    int n = 0;

    s->pid = -1;
    s->port = -1;
    if (pipe(p) != 0) {
        return -1;
    }
    snprintf(fdarg, sizeof fdarg, "%d", p[1]);
    for (int i = 0; prefix != NULL && prefix[i] != NULL && n < 50; i++) {
        args[n++] = prefix[i];
    }
    for (int i = 0; argv[i] != NULL && n < 60; i++) {
        args[n++] = argv[i];
    }
    args[n++] = "--ready-fd";
    args[n++] = fdarg;
    args[n] = NULL;

    pid_t pid = fork();
    if (pid < 0) {
        close(p[0]);
        close(p[1]);
        return -1;
    }
    if (pid == 0) {
        close(p[0]);
        execvp(args[0], (char *const *)args);
        _exit(127);
    }
    close(p[1]);
    s->pid = pid;

    char line[64];
    size_t len = 0;
    for (;;) {
        struct pollfd pfd = {p[0], POLLIN, 0};
        int rc = poll(&pfd, 1, timeout_ms);
        if (rc <= 0) {
            break; /* timeout (or error): not ready */
        }
        ssize_t got = read(p[0], line + len, sizeof line - 1 - len);
        if (got <= 0) {
            break; /* closed before a full line: server died */
        }
        len += (size_t)got;
        line[len] = '\0';
        if (strchr(line, '\n') != NULL) {
            close(p[0]);
            if (sscanf(line, "ready tcp %d", &s->port) == 1 || strncmp(line, "ready rtu", 9) == 0) {
                return 0;
            }
            (void)mbt_server_stop(s);
            return -1;
        }
    }
    close(p[0]);
    (void)mbt_server_stop(s);
    return -1;
}

int mbt_server_stop(mbt_server_t *s)
{
    int status = 0;
    if (s->pid <= 0) {
        return -1;
    }
    kill(s->pid, SIGTERM);
    while (waitpid(s->pid, &status, 0) < 0 && errno == EINTR) {
    }
    s->pid = -1;
    if (WIFEXITED(status)) {
        return WEXITSTATUS(status);
    }
    return WIFSIGNALED(status) ? 128 + WTERMSIG(status) : -1;
}

long mbt_read_file(const char *path, uint8_t *buf, size_t cap)
{
    FILE *f = fopen(path, "rb");
    if (f == NULL) {
        return -1;
    }
    size_t n = fread(buf, 1, cap, f);
    int bad = ferror(f) || fgetc(f) != EOF;
    fclose(f);
    return bad ? -1 : (long)n;
}

void mbt_put32(uint16_t *dst, uint32_t v, int wo)
{
    uint16_t hi = (uint16_t)(v >> 16), lo = (uint16_t)v;
    dst[0] = wo == ABBE_MB_WORD_ORDER_LOW_FIRST ? lo : hi;
    dst[1] = wo == ABBE_MB_WORD_ORDER_LOW_FIRST ? hi : lo;
}

uint32_t mbt_get32(const uint16_t *src, int wo)
{
    return wo == ABBE_MB_WORD_ORDER_LOW_FIRST ? ((uint32_t)src[1] << 16) | src[0]
                                              : ((uint32_t)src[0] << 16) | src[1];
}

int mbt_read32(modbus_t *ctx, int addr, int wo, uint32_t *v)
{
    uint16_t r[2];
    if (modbus_read_registers(ctx, addr, 2, r) != 2) {
        return -1;
    }
    *v = mbt_get32(r, wo);
    return 0;
}

int mbt_upload_begin(modbus_t *ctx)
{
    return modbus_write_register(ctx, ABBE_MB_REG_UP_CMD, ABBE_MB_UP_CMD_BEGIN) == 1 ? 0 : -1;
}

int mbt_upload_chunk(modbus_t *ctx, const uint8_t *blob, size_t off, size_t len)
{
    uint16_t regs[MODBUS_MAX_WRITE_REGISTERS];
    size_t nregs = (len + 1u) / 2u;
    if (nregs == 0 || nregs > MODBUS_MAX_WRITE_REGISTERS || (off & 1u) != 0u) {
        errno = EINVAL;
        return -1;
    }
    for (size_t i = 0; i < nregs; i++) {
        unsigned hi = blob[off + 2 * i];
        unsigned lo = 2 * i + 1 < len ? blob[off + 2 * i + 1] : 0u;
        regs[i] = (uint16_t)(hi << 8 | lo);
    }
    int rc = modbus_write_registers(ctx, (int)(ABBE_MB_REG_STAGING + off / 2u), (int)nregs, regs);
    return rc == (int)nregs ? 0 : -1;
}

int mbt_upload_commit(modbus_t *ctx, uint32_t len, uint32_t crc, int wo)
{
    uint16_t c[4];
    mbt_put32(&c[0], len, wo);
    mbt_put32(&c[2], crc, wo);
    return modbus_write_registers(ctx, ABBE_MB_REG_UP_COMMIT, 4, c) == 4 ? 0 : -1;
}

int mbt_upload(modbus_t *ctx, const uint8_t *blob, size_t len, uint32_t crc, int chunk_regs, int wo)
{
    if (mbt_upload_begin(ctx) != 0) {
        return -1;
    }
    size_t step = 2u * (size_t)chunk_regs;
    for (size_t off = 0; off < len; off += step) {
        if (mbt_upload_chunk(ctx, blob, off, len - off < step ? len - off : step) != 0) {
            return -1;
        }
    }
    return mbt_upload_commit(ctx, (uint32_t)len, crc, wo);
}

int mbt_raw_exception(modbus_t *ctx, const uint8_t *pdu, int pdu_len)
{
    uint8_t raw[MODBUS_MAX_PDU_LENGTH + 1];
    uint8_t rsp[MODBUS_TCP_MAX_ADU_LENGTH];
    if (pdu_len < 1 || pdu_len > MODBUS_MAX_PDU_LENGTH) {
        return -1;
    }
    raw[0] = 1;
    memcpy(raw + 1, pdu, (size_t)pdu_len);
    if (modbus_send_raw_request(ctx, raw, pdu_len + 1) < 0) {
        return -1;
    }
    int len = modbus_receive_confirmation(ctx, rsp);
    if (len < 0) {
        return -1;
    }
    int hl = modbus_get_header_length(ctx);
    if (len < hl + 1) {
        return -1;
    }
    return (rsp[hl] & 0x80) ? rsp[hl + 1] : 0;
}

modbus_t *mbt_tcp_client(int port)
{
    modbus_t *ctx = modbus_new_tcp("127.0.0.1", port);
    if (ctx == NULL) {
        return NULL;
    }
    modbus_set_response_timeout(ctx, 5, 0);
    if (modbus_connect(ctx) != 0) {
        modbus_free(ctx);
        return NULL;
    }
    return ctx;
}
