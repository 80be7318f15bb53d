/* abbe CAN port: Linux/POSIX parts.
 *
 * - the file-descriptor target of abbe_can_driver.h: each record is one
 *   struct can_frame (CAN_MTU, 16 bytes), as a CAN_RAW socket delivers it; any
 *   fd that keeps record boundaries works (socketpair(AF_UNIX, SOCK_SEQPACKET)
 *   in tests and tools, SOCK_DGRAM);
 * - opening a SocketCAN raw socket with receive filters for the frame map;
 * - loading a model file into a node.
 */
#ifndef ABBE_CAN_LINUX_H
#define ABBE_CAN_LINUX_H

#include <stddef.h>

#include "abbe_can.h"
#include "abbe_can_driver.h"

/* Bytes of one record on the fd (sizeof(struct can_frame)). */
#define ABBE_CAN_RECORD_SIZE 16u

typedef struct {
    int fd;
} abbe_can_fd_t;

/* Make *drv a driver over fd (not owned: the caller opens and closes it).
 * The driver never blocks: fd should be non-blocking (abbe_can_fd_nonblock). */
void abbe_can_fd_driver_init(abbe_can_fd_t *st, int fd, abbe_can_driver_t *drv);

/* One record <-> one frame. Read: ABBE_CAN_OK, ABBE_CAN_E_AGAIN,
 * ABBE_CAN_E_FRAME (record of another size, including an empty one;
 * consumed), ABBE_CAN_E_CLOSED (end of file: on a SOCK_SEQPACKET socket, the
 * peer has shut down and nothing is left to read), ABBE_CAN_E_IO (errno
 * set). Write: ABBE_CAN_OK, ABBE_CAN_E_AGAIN, ABBE_CAN_E_CLOSED (EPIPE),
 * ABBE_CAN_E_IO. */
int abbe_can_fd_read(int fd, abbe_can_frame_t *frame);
int abbe_can_fd_write(int fd, const abbe_can_frame_t *frame);

/* Set O_NONBLOCK. ABBE_CAN_OK or ABBE_CAN_E_IO. */
int abbe_can_fd_nonblock(int fd);

/* Open a non-blocking CAN_RAW socket bound to ifname, with receive filters
 * for the SYNC, the drives' TPDOs, the command and the temperature id (data
 * and remote frames of those ids), and all error frames. Returns ABBE_CAN_OK with *fd set,
 * ABBE_CAN_E_UNSUPPORTED if the kernel has no SocketCAN, ABBE_CAN_E_IO
 * otherwise; why (may be NULL) gets a sentence naming the failed call. */
int abbe_can_socket_open(const char *ifname, const abbe_can_config_t *cfg, int *fd, char *why,
                         size_t why_size);

/* Read the model file at path into the node's spare slot and queue it for the
 * next SYNC (abbe_can_node_commit_model). Returns ABBE_CAN_OK, ABBE_CAN_E_BUSY,
 * ABBE_CAN_E_IO, ABBE_CAN_E_TOO_BIG or the core's validation status; why (may
 * be NULL) gets a sentence for the log, e.g.
 * "model.bin refused: CRC-32 mismatch (ABBE_E_CRC); running model 0x1234abcd kept". */
int abbe_can_model_load_file(abbe_can_node_t *node, const char *path, char *why, size_t why_size);

#endif /* ABBE_CAN_LINUX_H */
