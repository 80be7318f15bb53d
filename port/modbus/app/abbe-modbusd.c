/* abbe-modbusd: the abbe compensator behind a Modbus TCP or RTU server.
 *
 *   abbe-modbusd --tcp 0.0.0.0:502 [--model model.bin] [--max-clients 4]
 *   abbe-modbusd --rtu /dev/ttyUSB0:115200[:E81] --unit 1 [--model model.bin]
 *
 * Register map: docs/modbus-registers.md. SIGTERM / SIGINT stop it cleanly
 * (exit status 0). --ready-fd N writes "ready tcp PORT\n" (or "ready rtu\n")
 * to file descriptor N once the server accepts requests, then closes N: start
 * it from a test with a pipe and port 0, read the line, stop it by pid.
 */
#define _POSIX_C_SOURCE 200809L

#include <errno.h>
#include <limits.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "abbe/modbus_server.h"

static abbe_mb_regs_t regs;      /* ~50 KiB: three table banks */
static abbe_mb_server_t server;
static uint8_t model_buf[ABBE_MB_STAGING_MAX];
static volatile sig_atomic_t stop_requested;

static void on_signal(int sig)
{
    (void)sig;
    stop_requested = 1;
}

/* ---- -v: the log (port/modbus/README.md "Log") ------------------------------------ */

static int rtu_mode;

static const char *result_name(int16_t result)
{
    switch (result) {
    case ABBE_MB_UP_OK: return "OK";
    case ABBE_MB_UP_NONE: return "NONE";
    case ABBE_MB_UP_INCOMPLETE: return "INCOMPLETE";
    case ABBE_MB_UP_CRC_MISMATCH: return "CRC_MISMATCH";
    case ABBE_MB_UP_LENGTH: return "LENGTH";
    case ABBE_MB_UP_ABORTED: return "ABORTED";
    case ABBE_MB_UP_DISCONNECTED: return "DISCONNECTED";
    case ABBE_MB_UP_TIMEOUT: return "TIMEOUT";
    default: return result < 0 && result > -100 ? "table refused" : "unknown result";
    }
}

/* "connection 3", or "the serial line" (RTU has one master) */
static const char *who(uint32_t conn, char *buf, size_t size)
{
    if (rtu_mode) {
        return "the serial line";
    }
    snprintf(buf, size, "connection %lu", (unsigned long)conn);
    return buf;
}

static void on_regs_event(void *ctx, const abbe_mb_event_t *ev)
{
    (void)ctx;
    char a[32], b[32];
    switch (ev->kind) {
    case ABBE_MB_EV_UPLOAD_BEGIN:
        fprintf(stderr, "abbe-modbusd: upload session %u begun by %s\n", (unsigned)ev->session,
                who(ev->conn, a, sizeof a));
        break;
    case ABBE_MB_EV_UPLOAD_END:
        if (ev->result == ABBE_MB_UP_OK) {
            fprintf(stderr,
                    "abbe-modbusd: upload session %u (%s) ended: OK, table CRC-32 0x%08lX, %lu bytes, "
                    "queued for the next cycle\n",
                    (unsigned)ev->session, who(ev->conn, a, sizeof a), (unsigned long)ev->crc,
                    (unsigned long)ev->size);
        } else if (ev->result < 0 && ev->result > -100) {
            fprintf(stderr, "abbe-modbusd: upload session %u (%s) ended: table refused (%d): %s\n",
                    (unsigned)ev->session, who(ev->conn, a, sizeof a), (int)ev->result,
                    abbe_strerror(ev->result));
        } else {
            fprintf(stderr, "abbe-modbusd: upload session %u (%s) ended: %s (%d)\n", (unsigned)ev->session,
                    who(ev->conn, a, sizeof a), result_name(ev->result), (int)ev->result);
        }
        break;
    case ABBE_MB_EV_UPLOAD_BUSY:
        fprintf(stderr, "abbe-modbusd: upload BEGIN from %s refused: session %u of %s is open (busy)\n",
                who(ev->conn, a, sizeof a), (unsigned)ev->session, who(ev->owner, b, sizeof b));
        break;
    case ABBE_MB_EV_MODEL_SWAP:
        fprintf(stderr, "abbe-modbusd: table CRC-32 0x%08lX (%lu bytes) in use from the cycle with IN_CYCLE %u\n",
                (unsigned long)ev->crc, (unsigned long)ev->size, (unsigned)ev->cycle);
        break;
    }
}

static void on_conn_event(void *ctx, const abbe_mb_conn_event_t *ev)
{
    (void)ctx;
    switch (ev->kind) {
    case ABBE_MB_CONN_OPENED:
        fprintf(stderr, "abbe-modbusd: connection %lu from %s opened (%u of %u open)\n", (unsigned long)ev->conn,
                ev->peer, (unsigned)ev->open, (unsigned)ev->max);
        break;
    case ABBE_MB_CONN_CLOSED:
        fprintf(stderr, "abbe-modbusd: connection %lu from %s closed: %s (%u of %u open)\n",
                (unsigned long)ev->conn, ev->peer, ev->reason, (unsigned)ev->open, (unsigned)ev->max);
        break;
    case ABBE_MB_CONN_REFUSED:
        fprintf(stderr, "abbe-modbusd: connection from %s refused: %s (%u of %u open)\n", ev->peer, ev->reason,
                (unsigned)ev->open, (unsigned)ev->max);
        break;
    }
}

static void usage(FILE *f)
{
    fprintf(f,
            "usage: abbe-modbusd (--tcp HOST:PORT | --rtu DEVICE:BAUD[:PDS]) [options]\n"
            "  --tcp HOST:PORT        Modbus TCP; PORT 0 lets the system choose (see --ready-fd)\n"
            "  --rtu DEV:BAUD[:PDS]   Modbus RTU; PDS = parity N/E/O, data bits, stop bits (default N81)\n"
            "  --unit ID              RTU unit id, 1..247 (default 1)\n"
            "  --model FILE           table to run from the start (else upload one)\n"
            "  --max-clients N        TCP connections served at once, 1..%d (default 4)\n"
            "  --idle-timeout-ms MS   close a TCP connection silent this long (default 60000, 0 never)\n"
            "  --upload-timeout-ms MS drop an upload idle this long (default 10000, 0 never)\n"
            "  --word-order high|low  32-bit word order (default high: high word first)\n"
            "  --dir-from-position    derive the direction from position changes\n"
            "  --cycle-us US          the controller's IN_CYCLE period, us (thermal block's clock; default 1000)\n"
            "  --enable               enable the compensator at start\n"
            "  --ready-fd N           write \"ready ...\\n\" to fd N when serving, then close it\n"
            "  -v                     log connections and uploads to stderr\n",
            ABBE_MB_MAX_CLIENTS);
}

static int parse_long(const char *s, long lo, long hi, long *out)
{
    char *end = NULL;
    errno = 0;
    long v = strtol(s, &end, 10);
    if (errno != 0 || end == s || *end != '\0' || v < lo || v > hi) {
        return -1;
    }
    *out = v;
    return 0;
}

static int load_model(const char *path, size_t *size)
{
    FILE *f = fopen(path, "rb");
    if (f == NULL) {
        fprintf(stderr, "abbe-modbusd: %s: %s\n", path, strerror(errno));
        return -1;
    }
    size_t n = fread(model_buf, 1, sizeof model_buf, f);
    int more = fgetc(f) != EOF;
    int err = ferror(f);
    fclose(f);
    if (err || more) {
        fprintf(stderr, "abbe-modbusd: %s: %s\n", path,
                err ? "read error" : "larger than the staging area");
        return -1;
    }
    *size = n;
    return 0;
}

int main(int argc, char **argv)
{
    const char *tcp = NULL, *rtu = NULL, *model = NULL;
    long unit = 1, max_clients = 4, idle_ms = 60000, upload_ms = 10000, ready_fd = -1, cycle_us = 1000;
    int enable = 0, verbose = 0;
    abbe_mb_regs_config_t cfg;
    abbe_mb_regs_default_config(&cfg);

    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        const char *v = i + 1 < argc ? argv[i + 1] : NULL;
        int bad = 0;
        if (strcmp(a, "-h") == 0 || strcmp(a, "--help") == 0) {
            usage(stdout);
            return 0;
        } else if (strcmp(a, "-v") == 0) {
            verbose = 1;
            continue;
        } else if (strcmp(a, "--enable") == 0) {
            enable = 1;
            continue;
        } else if (strcmp(a, "--dir-from-position") == 0) {
            cfg.dir_source = 1;
            continue;
        }
        if (v == NULL) {
            fprintf(stderr, "abbe-modbusd: %s needs a value\n", a);
            return 2;
        }
        i++;
        if (strcmp(a, "--tcp") == 0) {
            tcp = v;
        } else if (strcmp(a, "--rtu") == 0) {
            rtu = v;
        } else if (strcmp(a, "--model") == 0) {
            model = v;
        } else if (strcmp(a, "--unit") == 0) {
            bad = parse_long(v, 1, 247, &unit);
        } else if (strcmp(a, "--max-clients") == 0) {
            bad = parse_long(v, 1, ABBE_MB_MAX_CLIENTS, &max_clients);
        } else if (strcmp(a, "--idle-timeout-ms") == 0) {
            bad = parse_long(v, 0, INT32_MAX, &idle_ms);
        } else if (strcmp(a, "--upload-timeout-ms") == 0) {
            bad = parse_long(v, 0, INT32_MAX, &upload_ms);
        } else if (strcmp(a, "--cycle-us") == 0) {
            bad = parse_long(v, 1, 10000000, &cycle_us);
        } else if (strcmp(a, "--ready-fd") == 0) {
            bad = parse_long(v, 0, INT_MAX, &ready_fd);
        } else if (strcmp(a, "--word-order") == 0) {
            bad = strcmp(v, "high") != 0 && strcmp(v, "low") != 0;
            cfg.word_order = strcmp(v, "low") == 0 ? ABBE_MB_WORD_ORDER_LOW_FIRST
                                                   : ABBE_MB_WORD_ORDER_HIGH_FIRST;
        } else {
            fprintf(stderr, "abbe-modbusd: unknown option %s\n", a);
            usage(stderr);
            return 2;
        }
        if (bad) {
            fprintf(stderr, "abbe-modbusd: %s: bad value '%s'\n", a, v);
            return 2;
        }
    }
    if ((tcp == NULL) == (rtu == NULL)) {
        fprintf(stderr, "abbe-modbusd: give exactly one of --tcp and --rtu\n");
        usage(stderr);
        return 2;
    }

    size_t size = 0;
    if (model != NULL && load_model(model, &size) != 0) {
        return 1;
    }
    cfg.max_clients = (uint16_t)(tcp != NULL ? max_clients : 1);
    cfg.upload_timeout_ms = (uint32_t)upload_ms;
    cfg.cycle_us = (uint32_t)cycle_us;
    abbe_status_t st = abbe_mb_regs_init(&regs, &cfg, model != NULL ? model_buf : NULL, size);
    if (st != ABBE_OK) {
        fprintf(stderr, "abbe-modbusd: %s: %s\n", model != NULL ? model : "config", abbe_strerror(st));
        return 1;
    }
    if (enable) {
        static const uint8_t one[2] = {0, 1};
        (void)abbe_mb_regs_write(&regs, 0, ABBE_MB_REG_CT_ENABLE, 1, one);
    }
    if (verbose) {
        rtu_mode = rtu != NULL;
        abbe_mb_regs_set_event_hook(&regs, on_regs_event, NULL);
    }

    char spec[256];
    int rc;
    if (tcp != NULL) {
        long port;
        char *colon;
        if (strlen(tcp) >= sizeof spec || (colon = strrchr(strcpy(spec, tcp), ':')) == NULL ||
            parse_long(colon + 1, 0, 65535, &port) != 0) {
            fprintf(stderr, "abbe-modbusd: --tcp wants HOST:PORT, got '%s'\n", tcp);
            return 2;
        }
        *colon = '\0';
        const char *host = spec[0] == '\0' || strcmp(spec, "*") == 0 ? NULL : spec;
        rc = abbe_mb_server_open_tcp(&server, &regs, host, (int)port, (int)max_clients,
                                     (uint32_t)idle_ms);
    } else {
        long baud;
        char parity = 'N';
        int data_bit = 8, stop_bit = 1;
        char *c1, *c2;
        if (strlen(rtu) >= sizeof spec || (c1 = strchr(strcpy(spec, rtu), ':')) == NULL) {
            fprintf(stderr, "abbe-modbusd: --rtu wants DEVICE:BAUD[:PDS], got '%s'\n", rtu);
            return 2;
        }
        *c1++ = '\0';
        if ((c2 = strchr(c1, ':')) != NULL) {
            *c2++ = '\0';
            if (strlen(c2) != 3 || strchr("NEO", c2[0]) == NULL || c2[1] < '5' || c2[1] > '8' ||
                (c2[2] != '1' && c2[2] != '2')) {
                fprintf(stderr, "abbe-modbusd: --rtu framing '%s': want e.g. N81, E81, O72\n", c2);
                return 2;
            }
            parity = c2[0];
            data_bit = c2[1] - '0';
            stop_bit = c2[2] - '0';
        }
        if (parse_long(c1, 1, 4000000, &baud) != 0) {
            fprintf(stderr, "abbe-modbusd: --rtu baud '%s'\n", c1);
            return 2;
        }
        rc = abbe_mb_server_open_rtu(&server, &regs, spec, (int)baud, parity, data_bit, stop_bit,
                                     (int)unit);
    }
    if (rc != 0) {
        fprintf(stderr, "abbe-modbusd: cannot open %s: %s\n", tcp != NULL ? tcp : rtu,
                modbus_strerror(errno));
        return 1;
    }
    if (verbose) {
        abbe_mb_server_set_conn_hook(&server, on_conn_event, NULL);
    }

    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = 0; /* no SA_RESTART: poll() returns EINTR */
    sigaction(SIGTERM, &sa, NULL);
    sigaction(SIGINT, &sa, NULL);
    signal(SIGPIPE, SIG_IGN);

    if (verbose) {
        if (tcp != NULL) {
            fprintf(stderr, "abbe-modbusd: serving tcp port %d\n", abbe_mb_server_port(&server));
        } else {
            fprintf(stderr, "abbe-modbusd: serving rtu %s unit %ld\n", rtu, unit);
        }
    }
    if (ready_fd >= 0) {
        int fd = (int)ready_fd;
        if (tcp != NULL) {
            dprintf(fd, "ready tcp %d\n", abbe_mb_server_port(&server));
        } else {
            dprintf(fd, "ready rtu\n");
        }
        close(fd);
    }

    int status = 0;
    while (!stop_requested) {
        if (abbe_mb_server_poll(&server, 100) < 0 && errno != EINTR) {
            fprintf(stderr, "abbe-modbusd: poll: %s\n", strerror(errno));
            status = 1;
            break;
        }
    }
    if (verbose) {
        fprintf(stderr, "abbe-modbusd: stopping\n");
    }
    abbe_mb_server_close(&server);
    return status;
}
