/* abbe CAN port: the poll loop over a driver, and the stub target (portable). */
#include <string.h>

#include "abbe_can_driver.h"

int abbe_can_node_poll(abbe_can_node_t *node, const abbe_can_driver_t *drv, unsigned max_frames)
{
    if (node == NULL || drv == NULL || drv->send == NULL || drv->recv == NULL) {
        return ABBE_CAN_E_ARG;
    }
    int handled = 0;
    while ((unsigned)handled < max_frames) {
        abbe_can_frame_t rx;
        int st = drv->recv(drv->ctx, &rx);
        if (st == ABBE_CAN_E_AGAIN) {
            break;
        }
        if (st == ABBE_CAN_E_FRAME) {
            abbe_can_node_count_malformed(node);
            handled++;
            continue;
        }
        if (st != ABBE_CAN_OK) {
            return st;
        }
        abbe_can_frame_t tx[ABBE_CAN_MAX_TX];
        size_t n_tx = 0;
        int kind = abbe_can_node_rx(node, &rx, tx, &n_tx);
        handled++;
        for (size_t i = 0; i < n_tx; i++) {
            if (drv->send(drv->ctx, &tx[i]) != ABBE_CAN_OK) {
                abbe_can_node_count_tx_error(node);
            }
        }
        if (kind == ABBE_CAN_RX_COMMAND && rx.data[0] == ABBE_CAN_CMD_RELOAD) {
            break; /* let the caller load the model before the next SYNC */
        }
    }
    return handled;
}

static int stub_send(void *ctx, const abbe_can_frame_t *frame)
{
    abbe_can_stub_t *s = (abbe_can_stub_t *)ctx;
    if (s->tx_count == ABBE_CAN_STUB_QUEUE) {
        s->tx_dropped++;
        return ABBE_CAN_E_AGAIN;
    }
    s->tx[(s->tx_head + s->tx_count) % ABBE_CAN_STUB_QUEUE] = *frame;
    s->tx_count++;
    return ABBE_CAN_OK;
}

static int stub_recv(void *ctx, abbe_can_frame_t *frame)
{
    abbe_can_stub_t *s = (abbe_can_stub_t *)ctx;
    if (s->rx_count == 0u) {
        return ABBE_CAN_E_AGAIN;
    }
    *frame = s->rx[s->rx_head];
    s->rx_head = (s->rx_head + 1u) % ABBE_CAN_STUB_QUEUE;
    s->rx_count--;
    return ABBE_CAN_OK;
}

void abbe_can_stub_init(abbe_can_stub_t *stub, abbe_can_driver_t *drv)
{
    if (stub == NULL) {
        return;
    }
    memset(stub, 0, sizeof *stub);
    if (drv != NULL) {
        drv->ctx = stub;
        drv->send = stub_send;
        drv->recv = stub_recv;
    }
}

int abbe_can_stub_inject(abbe_can_stub_t *stub, const abbe_can_frame_t *frame)
{
    if (stub == NULL || frame == NULL) {
        return ABBE_CAN_E_ARG;
    }
    if (stub->rx_count == ABBE_CAN_STUB_QUEUE) {
        return ABBE_CAN_E_AGAIN;
    }
    stub->rx[(stub->rx_head + stub->rx_count) % ABBE_CAN_STUB_QUEUE] = *frame;
    stub->rx_count++;
    return ABBE_CAN_OK;
}

int abbe_can_stub_take(abbe_can_stub_t *stub, abbe_can_frame_t *frame)
{
    if (stub == NULL || frame == NULL) {
        return ABBE_CAN_E_ARG;
    }
    if (stub->tx_count == 0u) {
        return ABBE_CAN_E_AGAIN;
    }
    *frame = stub->tx[stub->tx_head];
    stub->tx_head = (stub->tx_head + 1u) % ABBE_CAN_STUB_QUEUE;
    stub->tx_count--;
    return ABBE_CAN_OK;
}
