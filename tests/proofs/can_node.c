/* Eva harness: the CAN node's frame
 * handling (port/socketcan, abbe_can_node_rx) on any number of frames of any
 * identifier (flags included), any DLC 0..255 and any payload, SYNCs (a
 * compensator cycle) among them, for a node with every receive path enabled
 * (command, temperature, thermal, shared TPDO with a statusword) and no
 * model loaded (so a thermal frame is counted, not sampled: the thermal
 * runtime and a loaded model are outside this harness, docs/proofs.md). */
#include "__fc_builtin.h"

#include "abbe_can.h"

static abbe_can_node_t node;

int main(void)
{
    abbe_can_config_t cfg;
    abbe_can_config_defaults(&cfg);
    cfg.temp_enable = 1;
    cfg.temp_cob_id = 0x300u;
    cfg.thermal_enable = 1;
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        cfg.axis[j].node_id = (uint8_t)(1u + j);
        cfg.axis[j].increments_per_mm = 1000.0;
    }
    cfg.axis[0].tpdo_dlc = 8;
    cfg.axis[0].statusword_byte = 4;
    if (abbe_can_node_init(&node, &cfg) != ABBE_CAN_OK) {
        return 1;
    }
    abbe_can_frame_t tx[ABBE_CAN_MAX_TX];
    int last = 0;
    while (Frama_C_interval(0, 1)) {
        abbe_can_frame_t rx;
        Frama_C_make_unknown((char *)&rx, sizeof rx);
        size_t n_tx = 0;
        last = abbe_can_node_rx(&node, &rx, tx, &n_tx);
    }
    return last;
}
