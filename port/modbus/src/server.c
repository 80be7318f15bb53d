/* abbe Modbus port: libmodbus server loop (abbe/modbus_server.h). */
#define _POSIX_C_SOURCE 200809L

#include <arpa/inet.h>
#include <errno.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include "abbe/modbus_server.h"

#define TCP_HEADER 7          /* MBAP: transaction, protocol, length, unit */
#define MAX_ACCEPT_PER_POLL 16

uint32_t abbe_mb_now_ms(void)
{
    struct timespec ts;
    if (clock_gettime(CLOCK_MONOTONIC, &ts) != 0) {
        return 0;
    }
    uint64_t ms = (uint64_t)ts.tv_sec * 1000u + (uint64_t)ts.tv_nsec / 1000000u;
    return (uint32_t)(ms & 0xFFFFFFFFu);
}

static uint16_t be16(const uint8_t *p)
{
    return (uint16_t)(((unsigned)p[0] << 8) | p[1]);
}

static int set_nonblocking(int fd)
{
    int flags = fcntl(fd, F_GETFL, 0);
    return flags < 0 ? -1 : fcntl(fd, F_SETFL, flags | O_NONBLOCK);
}

static void server_reset(abbe_mb_server_t *srv, abbe_mb_regs_t *regs)
{
    memset(srv, 0, sizeof *srv);
    srv->regs = regs;
    srv->listen_fd = -1;
    srv->port = -1;
    for (int i = 0; i < ABBE_MB_MAX_CLIENTS; i++) {
        srv->client[i].fd = -1;
    }
}

/* ---- one request -------------------------------------------------------------- */

/* Validate and apply req (a whole ADU: hl header bytes, the PDU, crc_len
 * checksum bytes), then answer it through libmodbus. Returns 0, or -1 if the
 * reply could not be sent. */
static int handle(abbe_mb_server_t *srv, uint32_t conn, const uint8_t *req, int req_len, int hl,
                  int crc_len)
{
    const uint8_t *pdu = req + hl;
    int n = req_len - hl - crc_len;
    if (n < 1) {
        return 0;
    }
    uint8_t fc = pdu[0];
    int ex = 0;
    modbus_mapping_t map;
    memset(&map, 0, sizeof map);
    map.tab_registers = srv->scratch;
    map.tab_input_registers = srv->scratch;

    switch (fc) {
    case MODBUS_FC_READ_HOLDING_REGISTERS:
    case MODBUS_FC_READ_INPUT_REGISTERS: {
        if (n != 5) {
            ex = ABBE_MB_EX_ILLEGAL_VALUE;
            break;
        }
        uint16_t addr = be16(pdu + 1), cnt = be16(pdu + 3);
        ex = abbe_mb_regs_read(srv->regs, conn, addr, cnt, srv->scratch);
        map.start_registers = map.start_input_registers = addr;
        map.nb_registers = map.nb_input_registers = cnt;
        break;
    }
    case MODBUS_FC_WRITE_SINGLE_REGISTER: {
        if (n != 5) {
            ex = ABBE_MB_EX_ILLEGAL_VALUE;
            break;
        }
        uint16_t addr = be16(pdu + 1);
        ex = abbe_mb_regs_write(srv->regs, conn, addr, 1, pdu + 3);
        map.start_registers = addr;
        map.nb_registers = 1;
        break;
    }
    case MODBUS_FC_WRITE_MULTIPLE_REGISTERS: {
        if (n < 6) {
            ex = ABBE_MB_EX_ILLEGAL_VALUE;
            break;
        }
        uint16_t addr = be16(pdu + 1), cnt = be16(pdu + 3);
        if (cnt < 1u || cnt > MODBUS_MAX_WRITE_REGISTERS || pdu[5] != 2u * cnt || n != 6 + pdu[5]) {
            ex = ABBE_MB_EX_ILLEGAL_VALUE;
            break;
        }
        ex = abbe_mb_regs_write(srv->regs, conn, addr, cnt, pdu + 6);
        map.start_registers = addr;
        map.nb_registers = cnt;
        break;
    }
    case MODBUS_FC_WRITE_AND_READ_REGISTERS: {
        if (n < 10) {
            ex = ABBE_MB_EX_ILLEGAL_VALUE;
            break;
        }
        uint16_t raddr = be16(pdu + 1), rcnt = be16(pdu + 3);
        uint16_t waddr = be16(pdu + 5), wcnt = be16(pdu + 7);
        if (rcnt < 1u || rcnt > MODBUS_MAX_WR_READ_REGISTERS || wcnt < 1u ||
            wcnt > MODBUS_MAX_WR_WRITE_REGISTERS || pdu[9] != 2u * wcnt || n != 10 + pdu[9]) {
            ex = ABBE_MB_EX_ILLEGAL_VALUE;
            break;
        }
        uint32_t rend = (uint32_t)raddr + rcnt, wend = (uint32_t)waddr + wcnt;
        if (rend > ABBE_MB_REG_STAGING || wend > ABBE_MB_REG_STAGING) {
            ex = ABBE_MB_EX_ILLEGAL_ADDRESS; /* FC23 is for the register map, not the staging area */
            break;
        }
        ex = abbe_mb_regs_check_read(srv->regs, conn, raddr, rcnt);
        if (ex == 0) {
            ex = abbe_mb_regs_write(srv->regs, conn, waddr, wcnt, pdu + 10);
        }
        if (ex == 0) {
            uint16_t start = raddr < waddr ? raddr : waddr;
            uint32_t end = rend > wend ? rend : wend;
            ex = abbe_mb_regs_read(srv->regs, conn, raddr, rcnt, &srv->scratch[raddr - start]);
            map.start_registers = start;
            map.nb_registers = (int)(end - start);
        }
        break;
    }
    default:
        ex = ABBE_MB_EX_ILLEGAL_FUNCTION;
        break;
    }

    abbe_mb_regs_count_request(srv->regs, fc, ex);
    if (srv->rtu && req[0] == MODBUS_BROADCAST_ADDRESS) {
        return 0; /* RTU broadcast: applied, never answered */
    }
    int rc = ex != 0 ? modbus_reply_exception(srv->ctx, req, (unsigned)ex)
                     : modbus_reply(srv->ctx, req, req_len, &map);
    return rc < 0 ? -1 : 0;
}

/* ---- TCP --------------------------------------------------------------------------- */

static uint16_t open_clients(const abbe_mb_server_t *srv)
{
    uint16_t n = 0;
    for (int i = 0; i < ABBE_MB_MAX_CLIENTS; i++) {
        n = (uint16_t)(n + (srv->client[i].fd >= 0));
    }
    return n;
}

static void conn_event(const abbe_mb_server_t *srv, abbe_mb_conn_event_kind_t kind, uint32_t conn,
                       const char *peer, const char *reason)
{
    if (srv->conn_fn == NULL) {
        return;
    }
    abbe_mb_conn_event_t ev;
    ev.kind = kind;
    ev.conn = conn;
    ev.peer = peer;
    ev.reason = reason != NULL ? reason : "";
    ev.open = open_clients(srv);
    ev.max = (uint16_t)srv->max_clients;
    srv->conn_fn(srv->conn_ctx, &ev);
}

/* "ADDRESS:PORT" of an accepted socket's peer. */
static void peer_text(const struct sockaddr_storage *ss, char *buf, size_t size)
{
    char host[INET6_ADDRSTRLEN];
    if (ss->ss_family == AF_INET) {
        const struct sockaddr_in *a = (const struct sockaddr_in *)(const void *)ss;
        if (inet_ntop(AF_INET, &a->sin_addr, host, sizeof host) != NULL) {
            snprintf(buf, size, "%s:%u", host, (unsigned)ntohs(a->sin_port));
            return;
        }
    } else if (ss->ss_family == AF_INET6) {
        const struct sockaddr_in6 *a = (const struct sockaddr_in6 *)(const void *)ss;
        if (inet_ntop(AF_INET6, &a->sin6_addr, host, sizeof host) != NULL) {
            snprintf(buf, size, "[%s]:%u", host, (unsigned)ntohs(a->sin6_port));
            return;
        }
    }
    snprintf(buf, size, "?");
}

static void client_close(abbe_mb_server_t *srv, abbe_mb_client_t *c, const char *reason)
{
    if (c->fd < 0) {
        return;
    }
    close(c->fd);
    c->fd = -1;
    conn_event(srv, ABBE_MB_CONN_CLOSED, c->conn, c->peer, reason);
    abbe_mb_regs_disconnect(srv->regs, c->conn); /* drops its upload session, if any */
    c->len = 0;
    c->conn = 0;
    abbe_mb_regs_set_clients(srv->regs, open_clients(srv), srv->refused);
}

static void accept_clients(abbe_mb_server_t *srv, uint32_t now)
{
    for (int k = 0; k < MAX_ACCEPT_PER_POLL; k++) {
        struct sockaddr_storage ss;
        socklen_t sl = sizeof ss;
        memset(&ss, 0, sizeof ss);
        int fd = accept(srv->listen_fd, (struct sockaddr *)&ss, &sl);
        if (fd < 0) {
            return; /* EAGAIN: no more pending; other errors: try next poll */
        }
        char peer[ABBE_MB_PEER_MAX];
        peer_text(&ss, peer, sizeof peer);
        abbe_mb_client_t *slot = NULL;
        if (open_clients(srv) < (uint16_t)srv->max_clients) {
            for (int i = 0; i < ABBE_MB_MAX_CLIENTS && slot == NULL; i++) {
                if (srv->client[i].fd < 0) {
                    slot = &srv->client[i];
                }
            }
        }
        if (slot == NULL || set_nonblocking(fd) != 0) {
            close(fd);
            srv->refused++;
            abbe_mb_regs_set_clients(srv->regs, open_clients(srv), srv->refused);
            conn_event(srv, ABBE_MB_CONN_REFUSED, 0, peer,
                       slot == NULL ? "all connections in use" : "cannot make the socket non-blocking");
            continue;
        }
        int one = 1;
        (void)setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
        srv->next_conn = srv->next_conn == UINT32_MAX ? 1u : srv->next_conn + 1u;
        slot->fd = fd;
        slot->conn = srv->next_conn;
        slot->len = 0;
        slot->last_rx_ms = now;
        memcpy(slot->peer, peer, sizeof slot->peer);
        abbe_mb_regs_set_clients(srv->regs, open_clients(srv), srv->refused);
        conn_event(srv, ABBE_MB_CONN_OPENED, slot->conn, slot->peer, "");
    }
}

/* Read what is there and answer every complete request. Returns the number
 * answered; closes the connection on EOF, errors and protocol violations. */
static int client_serve(abbe_mb_server_t *srv, abbe_mb_client_t *c, uint32_t now)
{
    ssize_t got = recv(c->fd, c->buf + c->len, sizeof c->buf - c->len, 0);
    if (got == 0) {
        client_close(srv, c, "closed by the client");
        return 0;
    }
    if (got < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR) {
        char why[96];
        snprintf(why, sizeof why, "receive error: %s", strerror(errno));
        client_close(srv, c, why);
        return 0;
    }
    if (got < 0) {
        return 0;
    }
    c->len = (uint16_t)(c->len + (uint16_t)got);
    c->last_rx_ms = now;
    int served = 0;
    while (c->len >= TCP_HEADER) {
        uint16_t protocol = be16(c->buf + 2), length = be16(c->buf + 4);
        if (protocol != 0u || length < 2u || length > MODBUS_TCP_MAX_ADU_LENGTH - 6u) {
            char why[96];
            snprintf(why, sizeof why, "not Modbus/TCP (protocol id %u, length %u)", (unsigned)protocol,
                     (unsigned)length);
            client_close(srv, c, why); /* no way to find the next frame */
            return served;
        }
        uint16_t total = (uint16_t)(6u + length);
        if (c->len < total) {
            break;
        }
        modbus_set_socket(srv->ctx, c->fd);
        int rc = handle(srv, c->conn, c->buf, total, TCP_HEADER, 0);
        modbus_set_socket(srv->ctx, -1);
        if (rc < 0) {
            client_close(srv, c, "the answer could not be sent at once (client gone or not reading)");
            return served;
        }
        served++;
        memmove(c->buf, c->buf + total, (size_t)(c->len - total));
        c->len = (uint16_t)(c->len - total);
    }
    return served;
}

int abbe_mb_server_open_tcp(abbe_mb_server_t *srv, abbe_mb_regs_t *regs, const char *ip, int port,
                            int max_clients, uint32_t idle_timeout_ms)
{
    if (srv == NULL || regs == NULL || port < 0 || port > 65535 || max_clients < 1 ||
        max_clients > ABBE_MB_MAX_CLIENTS) {
        errno = EINVAL;
        return -1;
    }
    server_reset(srv, regs);
    srv->max_clients = max_clients;
    srv->idle_timeout_ms = idle_timeout_ms;
    srv->ctx = modbus_new_tcp(ip, port);
    if (srv->ctx == NULL) {
        return -1;
    }
    srv->listen_fd = modbus_tcp_listen(srv->ctx, max_clients);
    if (srv->listen_fd < 0 || set_nonblocking(srv->listen_fd) != 0) {
        int e = errno;
        abbe_mb_server_close(srv);
        errno = e;
        return -1;
    }
    struct sockaddr_in sa;
    socklen_t sl = sizeof sa;
    if (getsockname(srv->listen_fd, (struct sockaddr *)&sa, &sl) != 0) {
        int e = errno;
        abbe_mb_server_close(srv);
        errno = e;
        return -1;
    }
    srv->port = ntohs(sa.sin_port);
    abbe_mb_regs_set_clients(regs, 0, 0);
    return 0;
}

/* ---- RTU ------------------------------------------------------------------------------ */

int abbe_mb_server_open_rtu(abbe_mb_server_t *srv, abbe_mb_regs_t *regs, const char *device,
                            int baud, char parity, int data_bit, int stop_bit, int unit_id)
{
    if (srv == NULL || regs == NULL || device == NULL || baud <= 0 || unit_id < 1 || unit_id > 247) {
        errno = EINVAL;
        return -1;
    }
    server_reset(srv, regs);
    srv->rtu = 1;
    srv->max_clients = 1;
    srv->ctx = modbus_new_rtu(device, baud, parity, data_bit, stop_bit);
    if (srv->ctx == NULL) {
        return -1;
    }
    /* A started frame must complete within 50 ms (byte gaps far above 3.5
     * characters at any baud rate); a stalled master blocks no longer. */
    if (modbus_set_slave(srv->ctx, unit_id) != 0 || modbus_set_byte_timeout(srv->ctx, 0, 50000) != 0 ||
        modbus_set_indication_timeout(srv->ctx, 0, 50000) != 0 || modbus_connect(srv->ctx) != 0) {
        int e = errno;
        modbus_free(srv->ctx);
        srv->ctx = NULL;
        errno = e;
        return -1;
    }
    return 0;
}

static int rtu_serve(abbe_mb_server_t *srv, uint32_t now)
{
    uint8_t req[MODBUS_RTU_MAX_ADU_LENGTH];
    int len = modbus_receive(srv->ctx, req);
    if (len > 0) {
        int rc = handle(srv, 1u, req, len, modbus_get_header_length(srv->ctx), 2);
        return rc < 0 ? 0 : 1;
    }
    if (len < 0) {
        if (errno == EIO || errno == EBADF || errno == ENXIO || errno == ECONNRESET) {
            srv->quiet_until_ms = now + 200u; /* line hung up: look again later */
        } else if (errno == ETIMEDOUT) {
            modbus_flush(srv->ctx); /* a frame stopped short: drop what is left of it */
        }
        /* A CRC error consumed exactly one frame: the next one is intact. */
    }
    return 0;
}

/* ---- the loop ----------------------------------------------------------------------------- */

int abbe_mb_server_poll(abbe_mb_server_t *srv, int timeout_ms)
{
    if (srv == NULL || srv->ctx == NULL) {
        errno = EINVAL;
        return -1;
    }
    struct pollfd pfd[ABBE_MB_MAX_CLIENTS + 1];
    abbe_mb_client_t *who[ABBE_MB_MAX_CLIENTS + 1];
    nfds_t n = 0;
    uint32_t now = abbe_mb_now_ms();

    if (srv->rtu) {
        if ((int32_t)(now - srv->quiet_until_ms) >= 0) {
            pfd[n].fd = modbus_get_socket(srv->ctx);
            pfd[n].events = POLLIN;
            who[n++] = NULL;
        }
    } else {
        pfd[n].fd = srv->listen_fd;
        pfd[n].events = POLLIN;
        who[n++] = NULL;
        for (int i = 0; i < ABBE_MB_MAX_CLIENTS; i++) {
            if (srv->client[i].fd >= 0) {
                pfd[n].fd = srv->client[i].fd;
                pfd[n].events = POLLIN;
                who[n++] = &srv->client[i];
            }
        }
    }

    int rc = poll(pfd, n, timeout_ms);
    if (rc < 0) {
        return -1;
    }
    now = abbe_mb_now_ms();
    abbe_mb_regs_tick(srv->regs, now);
    int served = 0;
    for (nfds_t k = 0; k < n && rc > 0; k++) {
        short ev = pfd[k].revents;
        if (ev == 0) {
            continue;
        }
        if (srv->rtu) {
            if (ev & POLLIN) {
                served += rtu_serve(srv, now);
            } else {
                srv->quiet_until_ms = now + 200u;
            }
        } else if (who[k] == NULL) {
            accept_clients(srv, now);
        } else if (ev & POLLIN) {
            served += client_serve(srv, who[k], now);
        } else {
            client_close(srv, who[k], (ev & POLLHUP) ? "hung up" : "socket error"); /* no data */
        }
    }
    if (!srv->rtu && srv->idle_timeout_ms != 0u) {
        for (int i = 0; i < ABBE_MB_MAX_CLIENTS; i++) {
            abbe_mb_client_t *c = &srv->client[i];
            if (c->fd >= 0 && (uint32_t)(now - c->last_rx_ms) >= srv->idle_timeout_ms) {
                char why[64];
                snprintf(why, sizeof why, "idle for %lu ms", (unsigned long)srv->idle_timeout_ms);
                client_close(srv, c, why);
            }
        }
    }
    return served;
}

void abbe_mb_server_set_conn_hook(abbe_mb_server_t *srv, abbe_mb_conn_fn fn, void *ctx)
{
    if (srv != NULL) {
        srv->conn_fn = fn;
        srv->conn_ctx = ctx;
    }
}

int abbe_mb_server_port(const abbe_mb_server_t *srv)
{
    return srv != NULL && !srv->rtu ? srv->port : -1;
}

void abbe_mb_server_close(abbe_mb_server_t *srv)
{
    if (srv == NULL) {
        return;
    }
    for (int i = 0; i < ABBE_MB_MAX_CLIENTS; i++) {
        client_close(srv, &srv->client[i], "server stopping");
    }
    if (srv->listen_fd >= 0) {
        close(srv->listen_fd);
        srv->listen_fd = -1;
    }
    if (srv->ctx != NULL) {
        if (srv->rtu) {
            modbus_close(srv->ctx);
        } else {
            modbus_set_socket(srv->ctx, -1);
        }
        modbus_free(srv->ctx);
        srv->ctx = NULL;
    }
}
