/* abbe Modbus port: a libmodbus server around the register map (POSIX).
 *
 * One thread, one poll() loop: the TCP listening socket and up to max_clients
 * connections (more are accepted and closed at once), or one serial line (RTU).
 * TCP requests are framed here from non-blocking sockets (a client that sends
 * half a request or stops reading its replies never stalls the others) and
 * answered with modbus_reply() / modbus_reply_exception(). No allocation after
 * open. Functions follow libmodbus: -1 and errno on failure.
 */
#ifndef ABBE_MODBUS_SERVER_H
#define ABBE_MODBUS_SERVER_H

#include <stdint.h>

#include <modbus.h>

#include "abbe/modbus_port.h"

/* Compile-time cap on TCP connections served at once. */
#ifndef ABBE_MB_MAX_CLIENTS
#define ABBE_MB_MAX_CLIENTS 16
#endif
#if ABBE_MB_MAX_CLIENTS < 1 || ABBE_MB_MAX_CLIENTS > 255
#error "ABBE_MB_MAX_CLIENTS must be in [1, 255]"
#endif

/* A TCP connection opened, closed or refused, reported to a connection hook
 * (abbe_mb_server_set_conn_hook), e.g. for a log. */
typedef enum {
    ABBE_MB_CONN_OPENED = 1,
    ABBE_MB_CONN_CLOSED = 2,
    ABBE_MB_CONN_REFUSED = 3 /* accepted and closed at once */
} abbe_mb_conn_event_kind_t;

typedef struct {
    abbe_mb_conn_event_kind_t kind;
    uint32_t conn;       /* the register map's token of the connection (0: refused) */
    const char *peer;    /* "ADDRESS:PORT" of the client */
    const char *reason;  /* CLOSED, REFUSED: why, a sentence fragment; else "" */
    uint16_t open;       /* connections open after the event */
    uint16_t max;        /* connections served at once */
} abbe_mb_conn_event_t;

typedef void (*abbe_mb_conn_fn)(void *ctx, const abbe_mb_conn_event_t *ev);

#define ABBE_MB_PEER_MAX 64 /* "[v6 address]:port" */

/* One TCP connection. All fields private. */
typedef struct {
    int fd;                                  /* -1: slot free */
    uint32_t conn;                           /* token for the register map */
    uint32_t last_rx_ms;
    uint16_t len;
    uint8_t buf[MODBUS_TCP_MAX_ADU_LENGTH];  /* partial request(s) */
    char peer[ABBE_MB_PEER_MAX];
} abbe_mb_client_t;

/* Server state. Allocate it yourself; all fields private. */
typedef struct {
    abbe_mb_regs_t *regs;
    modbus_t *ctx;
    int rtu;
    int listen_fd;
    int port;
    int max_clients;
    uint32_t idle_timeout_ms;
    uint32_t next_conn;
    uint32_t refused;
    uint32_t quiet_until_ms;  /* RTU: line hung up, poll it again from then */
    abbe_mb_conn_fn conn_fn;  /* connection hook, NULL: none */
    void *conn_ctx;
    abbe_mb_client_t client[ABBE_MB_MAX_CLIENTS];
    uint16_t scratch[ABBE_MB_REG_STAGING];  /* FC23 spans at most the register map below the staging area */
} abbe_mb_server_t;

/* Listen on ip:port (ip NULL = any; port 0 = chosen by the system, see
 * abbe_mb_server_port()). max_clients in [1, ABBE_MB_MAX_CLIENTS]; a
 * connection without a request for idle_timeout_ms is closed (0 = never).
 * Returns 0, or -1 with errno (EINVAL for bad arguments, or from
 * libmodbus / the socket calls). */
int abbe_mb_server_open_tcp(abbe_mb_server_t *srv, abbe_mb_regs_t *regs, const char *ip, int port,
                            int max_clients, uint32_t idle_timeout_ms);

/* Serve the serial line device as RTU unit unit_id (1..247), e.g.
 * ("/dev/ttyUSB0", 115200, 'E', 8, 1, 1). Returns 0, or -1 with errno. */
int abbe_mb_server_open_rtu(abbe_mb_server_t *srv, abbe_mb_regs_t *regs, const char *device,
                            int baud, char parity, int data_bit, int stop_bit, int unit_id);

/* The TCP port listened on (after port 0, the one the system chose); -1 for RTU. */
int abbe_mb_server_port(const abbe_mb_server_t *srv);

/* Wait up to timeout_ms for traffic and serve it: accept / refuse connections,
 * answer every complete request, close dead or idle connections, expire an
 * idle upload. Returns the number of requests answered, or -1 with errno
 * (EINTR when a signal interrupted the wait: check your stop flag and call
 * again). */
int abbe_mb_server_poll(abbe_mb_server_t *srv, int timeout_ms);

/* Close every connection (dropping an open upload) and free the libmodbus
 * context. srv may then be opened again. */
void abbe_mb_server_close(abbe_mb_server_t *srv);

/* Call fn(ctx, event) for every TCP connection opened, closed (with the
 * reason) or refused. Set it after abbe_mb_server_open_tcp (which clears it);
 * NULL fn: none. The strings in the event live until fn returns. */
void abbe_mb_server_set_conn_hook(abbe_mb_server_t *srv, abbe_mb_conn_fn fn, void *ctx);

/* Milliseconds of CLOCK_MONOTONIC, wrapping (the register map's clock). */
uint32_t abbe_mb_now_ms(void);

#endif /* ABBE_MODBUS_SERVER_H */
