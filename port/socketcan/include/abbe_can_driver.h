/* abbe CAN port: the driver contract.
 *
 * A target moves single classic CAN frames; that is all the port needs.
 * Implement the two functions below for your CAN controller and hand them to
 * abbe_can_node_poll() (or call abbe_can_node_rx() yourself). Targets here:
 *   - file descriptor (abbe_can_linux.h): SocketCAN raw sockets, or any fd that
 *     carries struct can_frame records (a socketpair in tests and tools);
 *   - stub (below): two in-memory queues, compiles anywhere, for tests and as
 *     the starting point of a new target.
 *
 * Contract:
 *   send(ctx, frame)  queue one frame for transmission without blocking.
 *                     ABBE_CAN_OK, ABBE_CAN_E_AGAIN (queue full, frame
 *                     dropped), ABBE_CAN_E_CLOSED or ABBE_CAN_E_IO.
 *   recv(ctx, frame)  take one received frame without blocking.
 *                     ABBE_CAN_OK, ABBE_CAN_E_AGAIN (nothing pending),
 *                     ABBE_CAN_E_FRAME (a record that was not one frame; it is
 *                     consumed and counted), ABBE_CAN_E_CLOSED or ABBE_CAN_E_IO.
 * Waiting for a frame (poll, interrupt) is the target's business.
 */
#ifndef ABBE_CAN_DRIVER_H
#define ABBE_CAN_DRIVER_H

#include <stddef.h>
#include <stdint.h>

#include "abbe_can.h"

typedef struct {
    void *ctx;
    int (*send)(void *ctx, const abbe_can_frame_t *frame);
    int (*recv)(void *ctx, abbe_can_frame_t *frame);
} abbe_can_driver_t;

/* Receive and handle every frame available now (at most max_frames), sending
 * what the node produces. Stops early after a RELOAD command so the caller
 * can load the model before the next SYNC is handled. Returns the number of
 * frames handled (>= 0), or ABBE_CAN_E_CLOSED / ABBE_CAN_E_IO /
 * ABBE_CAN_E_ARG. Send failures are counted (tx_errors), not returned. */
int abbe_can_node_poll(abbe_can_node_t *node, const abbe_can_driver_t *drv, unsigned max_frames);

/* ---- stub target ---------------------------------------------------------- */

#define ABBE_CAN_STUB_QUEUE 32u

typedef struct {
    abbe_can_frame_t rx[ABBE_CAN_STUB_QUEUE];
    abbe_can_frame_t tx[ABBE_CAN_STUB_QUEUE];
    unsigned rx_head, rx_count;
    unsigned tx_head, tx_count;
    uint32_t tx_dropped;
} abbe_can_stub_t;

/* Empty queues; *drv then sends to stub->tx and receives from stub->rx. */
void abbe_can_stub_init(abbe_can_stub_t *stub, abbe_can_driver_t *drv);
/* Put a frame into the receive queue (ABBE_CAN_E_AGAIN if full). */
int abbe_can_stub_inject(abbe_can_stub_t *stub, const abbe_can_frame_t *frame);
/* Take the oldest sent frame (ABBE_CAN_E_AGAIN if none). */
int abbe_can_stub_take(abbe_can_stub_t *stub, abbe_can_frame_t *frame);

#endif /* ABBE_CAN_DRIVER_H */
