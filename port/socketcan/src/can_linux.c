/* abbe CAN port: file-descriptor target, SocketCAN socket, model files (Linux). */
#define _GNU_SOURCE /* POLLRDHUP: Linux only, like the rest of this file */

#include <errno.h>
#include <fcntl.h>
#include <net/if.h>
#include <poll.h>
#include <stdio.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <unistd.h>

#include <linux/can.h>
#include <linux/can/raw.h>

#include "abbe_can_linux.h"

/* The record layout this port writes is the kernel's. */
typedef char abbe_can_record_size_check[(sizeof(struct can_frame) == ABBE_CAN_RECORD_SIZE) ? 1 : -1];

/* read() gave 0 bytes: the end of the stream, or a record of 0 bytes (which
 * SOCK_SEQPACKET and SOCK_DGRAM sockets deliver like any other record). */
static int zero_length_read(int fd)
{
    int type = 0;
    socklen_t len = sizeof type;
    if (getsockopt(fd, SOL_SOCKET, SO_TYPE, &type, &len) != 0) {
        return ABBE_CAN_E_CLOSED; /* not a socket (pipe, file): end of file */
    }
    if (type == SOCK_DGRAM || type == SOCK_RAW) {
        return ABBE_CAN_E_FRAME; /* datagram sockets have no end of stream */
    }
    if (type != SOCK_SEQPACKET) {
        return ABBE_CAN_E_CLOSED; /* a stream: end of stream */
    }
    /* SEQPACKET: the end of the stream only once the peer has shut down and
     * no record is left behind the empty one (FIONREAD sums the queued bytes). */
    struct pollfd p;
    p.fd = fd;
    p.events = POLLRDHUP;
    p.revents = 0;
    if (poll(&p, 1, 0) < 0) {
        return ABBE_CAN_E_IO;
    }
    if ((p.revents & (POLLRDHUP | POLLHUP)) == 0) {
        return ABBE_CAN_E_FRAME;
    }
    int queued = 0;
    if (ioctl(fd, FIONREAD, &queued) == 0 && queued > 0) {
        return ABBE_CAN_E_FRAME;
    }
    return ABBE_CAN_E_CLOSED;
}

int abbe_can_fd_read(int fd, abbe_can_frame_t *frame)
{
    if (frame == NULL) {
        return ABBE_CAN_E_ARG;
    }
    union {
        struct can_frame cf;
        uint8_t raw[sizeof(struct canfd_frame) + 1u]; /* larger records are detected, not split */
    } buf;
    ssize_t n;
    do {
        n = read(fd, &buf, sizeof buf);
    } while (n < 0 && errno == EINTR);
    if (n < 0) {
        if (errno == EAGAIN || errno == EWOULDBLOCK) {
            return ABBE_CAN_E_AGAIN;
        }
        if (errno == ECONNRESET) {
            return ABBE_CAN_E_CLOSED;
        }
        return ABBE_CAN_E_IO;
    }
    if (n == 0) {
        return zero_length_read(fd);
    }
    if ((size_t)n != sizeof(struct can_frame)) {
        return ABBE_CAN_E_FRAME;
    }
    frame->id = buf.cf.can_id;
    frame->dlc = buf.cf.can_dlc;
    memcpy(frame->data, buf.cf.data, sizeof frame->data);
    return ABBE_CAN_OK;
}

int abbe_can_fd_write(int fd, const abbe_can_frame_t *frame)
{
    if (frame == NULL) {
        return ABBE_CAN_E_ARG;
    }
    struct can_frame cf;
    memset(&cf, 0, sizeof cf);
    cf.can_id = frame->id;
    cf.can_dlc = frame->dlc > ABBE_CAN_MAX_DLEN ? (uint8_t)ABBE_CAN_MAX_DLEN : frame->dlc;
    memcpy(cf.data, frame->data, sizeof cf.data);
    ssize_t n;
    do {
        n = write(fd, &cf, sizeof cf);
    } while (n < 0 && errno == EINTR);
    if (n == (ssize_t)sizeof cf) {
        return ABBE_CAN_OK;
    }
    if (n >= 0) {
        return ABBE_CAN_E_IO; /* a partial record cannot happen on a record-preserving fd */
    }
    if (errno == EAGAIN || errno == EWOULDBLOCK || errno == ENOBUFS) {
        return ABBE_CAN_E_AGAIN;
    }
    if (errno == EPIPE || errno == ECONNRESET) {
        return ABBE_CAN_E_CLOSED;
    }
    return ABBE_CAN_E_IO;
}

int abbe_can_fd_nonblock(int fd)
{
    int fl = fcntl(fd, F_GETFL);
    if (fl < 0 || fcntl(fd, F_SETFL, fl | O_NONBLOCK) < 0) {
        return ABBE_CAN_E_IO;
    }
    return ABBE_CAN_OK;
}

static int fd_send(void *ctx, const abbe_can_frame_t *frame)
{
    return abbe_can_fd_write(((abbe_can_fd_t *)ctx)->fd, frame);
}

static int fd_recv(void *ctx, abbe_can_frame_t *frame)
{
    return abbe_can_fd_read(((abbe_can_fd_t *)ctx)->fd, frame);
}

void abbe_can_fd_driver_init(abbe_can_fd_t *st, int fd, abbe_can_driver_t *drv)
{
    if (st == NULL || drv == NULL) {
        return;
    }
    st->fd = fd;
    drv->ctx = st;
    drv->send = fd_send;
    drv->recv = fd_recv;
}

static int socket_fail(int s, int status, char *why, size_t why_size, const char *what, const char *ifname)
{
    int e = errno;
    if (why != NULL && why_size > 0u) {
        snprintf(why, why_size, "%s%s%s: %s%s", what, ifname != NULL ? " " : "", ifname != NULL ? ifname : "",
                 strerror(e),
                 status == ABBE_CAN_E_UNSUPPORTED ? " (this kernel has no SocketCAN: load the can and can_raw modules)"
                                                  : "");
    }
    if (s >= 0) {
        close(s);
    }
    errno = e;
    return status;
}

int abbe_can_socket_open(const char *ifname, const abbe_can_config_t *cfg, int *fd, char *why, size_t why_size)
{
    if (ifname == NULL || cfg == NULL || fd == NULL) {
        return ABBE_CAN_E_ARG;
    }
    int s = socket(PF_CAN, SOCK_RAW, CAN_RAW);
    if (s < 0) {
        int st = (errno == EAFNOSUPPORT || errno == EPROTONOSUPPORT) ? ABBE_CAN_E_UNSUPPORTED : ABBE_CAN_E_IO;
        return socket_fail(-1, st, why, why_size, "socket(PF_CAN, SOCK_RAW, CAN_RAW)", NULL);
    }
    unsigned idx = if_nametoindex(ifname);
    if (idx == 0u) {
        return socket_fail(s, ABBE_CAN_E_IO, why, why_size, "no CAN interface", ifname);
    }
    /* Standard-id data and remote frames of the ids the node reads; the RTR
     * bit is not in the mask so remote requests arrive and are counted. */
    struct can_filter filt[3 + ABBE_AXES];
    size_t n = 0;
    filt[n].can_id = cfg->sync_cob_id;
    filt[n++].can_mask = CAN_SFF_MASK | CAN_EFF_FLAG;
    if (cfg->command_enable) {
        filt[n].can_id = cfg->command_cob_id;
        filt[n++].can_mask = CAN_SFF_MASK | CAN_EFF_FLAG;
    }
    if (cfg->temp_enable) {
        filt[n].can_id = cfg->temp_cob_id;
        filt[n++].can_mask = CAN_SFF_MASK | CAN_EFF_FLAG;
    }
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        int dup = 0;
        for (unsigned k = 0; k < j; k++) {
            dup |= cfg->axis[k].tpdo_cob_id == cfg->axis[j].tpdo_cob_id;
        }
        if (!dup) {
            filt[n].can_id = cfg->axis[j].tpdo_cob_id;
            filt[n++].can_mask = CAN_SFF_MASK | CAN_EFF_FLAG;
        }
    }
    if (setsockopt(s, SOL_CAN_RAW, CAN_RAW_FILTER, filt, (socklen_t)(n * sizeof filt[0])) < 0) {
        return socket_fail(s, ABBE_CAN_E_IO, why, why_size, "setsockopt(CAN_RAW_FILTER)", NULL);
    }
    can_err_mask_t err_mask = CAN_ERR_MASK; /* every error class: counted and logged */
    if (setsockopt(s, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &err_mask, sizeof err_mask) < 0) {
        return socket_fail(s, ABBE_CAN_E_IO, why, why_size, "setsockopt(CAN_RAW_ERR_FILTER)", NULL);
    }
    struct sockaddr_can addr;
    memset(&addr, 0, sizeof addr);
    addr.can_family = AF_CAN;
    addr.can_ifindex = (int)idx;
    if (bind(s, (struct sockaddr *)&addr, sizeof addr) < 0) {
        return socket_fail(s, ABBE_CAN_E_IO, why, why_size, "bind to", ifname);
    }
    if (abbe_can_fd_nonblock(s) != ABBE_CAN_OK) {
        return socket_fail(s, ABBE_CAN_E_IO, why, why_size, "fcntl(O_NONBLOCK)", NULL);
    }
    *fd = s;
    if (why != NULL && why_size > 0u) {
        why[0] = '\0';
    }
    return ABBE_CAN_OK;
}

/* "running model 0x... kept" / "no model running" */
static void kept_text(char *kept, size_t size, uint32_t crc, int have_crc)
{
    if (have_crc) {
        snprintf(kept, size, "running model 0x%08lx kept", (unsigned long)crc);
    } else {
        snprintf(kept, size, "no model running");
    }
}

/* "model PATH refused: DETAIL (STATUS_NAME); KEPT" */
static int refuse(abbe_can_node_t *node, int status, int note, const char *path, const char *detail,
                  const char *kept, char *why, size_t why_size)
{
    if (note) {
        abbe_can_node_note_load_failure(node, status);
    }
    if (why != NULL && why_size > 0u) {
        snprintf(why, why_size, "model %s refused: %s (%s); %s", path, detail, abbe_can_status_name(status), kept);
    }
    return status;
}

int abbe_can_model_load_file(abbe_can_node_t *node, const char *path, char *why, size_t why_size)
{
    if (node == NULL || path == NULL) {
        return ABBE_CAN_E_ARG;
    }
    char kept[64], detail[160];
    kept_text(kept, sizeof kept, abbe_can_node_model_crc(node), abbe_comp_model(&node->comp) != NULL);
    size_t cap = 0;
    uint8_t *buf = abbe_can_node_model_buffer(node, &cap);
    if (buf == NULL) {
        return refuse(node, ABBE_CAN_E_BUSY, 1, path, abbe_can_strerror(ABBE_CAN_E_BUSY), kept, why, why_size);
    }
    int fd;
    do {
        fd = open(path, O_RDONLY | O_CLOEXEC);
    } while (fd < 0 && errno == EINTR);
    if (fd < 0) {
        snprintf(detail, sizeof detail, "cannot open: %s", strerror(errno));
        return refuse(node, ABBE_CAN_E_IO, 1, path, detail, kept, why, why_size);
    }
    size_t size = 0;
    int too_big = 0, io_errno = 0;
    for (;;) {
        uint8_t extra;
        uint8_t *dst = size < cap ? buf + size : &extra;
        size_t want = size < cap ? cap - size : 1u;
        ssize_t n = read(fd, dst, want);
        if (n < 0 && errno == EINTR) {
            continue;
        }
        if (n < 0) {
            io_errno = errno;
            break;
        }
        if (n == 0) {
            break;
        }
        if (size >= cap) {
            too_big = 1;
            break;
        }
        size += (size_t)n;
    }
    close(fd);
    if (io_errno != 0) {
        snprintf(detail, sizeof detail, "read error: %s", strerror(io_errno));
        return refuse(node, ABBE_CAN_E_IO, 1, path, detail, kept, why, why_size);
    }
    if (too_big) {
        snprintf(detail, sizeof detail, "file larger than %u bytes", (unsigned)ABBE_CAN_BLOB_MAX);
        return refuse(node, ABBE_CAN_E_TOO_BIG, 1, path, detail, kept, why, why_size);
    }
    int st = abbe_can_node_commit_model(node, size); /* counts the attempt itself */
    if (st != ABBE_CAN_OK) {
        return refuse(node, st, 0, path, abbe_can_strerror(st), kept, why, why_size);
    }
    if (why != NULL && why_size > 0u) {
        const abbe_model_t *m = &node->model[node->pending_slot];
        snprintf(why, why_size, "model %s loaded: CRC-32 0x%08lx, %lu bytes; takes effect at the next SYNC", path,
                 (unsigned long)abbe_model_crc(m), (unsigned long)abbe_model_size(m));
    }
    return ABBE_CAN_OK;
}
