/* Eva harness: the CAN node's frame
 * handling (port/socketcan, abbe_can_node_rx) on any number of frames of any
 * identifier (flags included), any DLC 0..255 and any payload, SYNCs (a
 * compensator cycle) among them, for a node with every receive path enabled
 * (command, temperature, thermal, shared TPDO with a statusword).
 *
 * Without PROOF_MODEL (can_node): no model loaded, so a thermal frame is
 * counted, not sampled.
 *
 * PROOF_MODEL (can_node_thermal): a model loaded first, through the node's
 * own upload path (abbe_can_node_load_model: the spare slot's buffer,
 * abbe_thermal_load, the swap queued): the golden format 1.3 table
 * (tests/golden/golden_thermal.c: the 3-axis layout and coefficients of the
 * thermal golden table, its thermal block of 17 inputs and 5 channels) with
 * ANY scalar field (tests/proofs/any_scalars.h: reference point, tool offset,
 * squareness, each axis' travel, periods, origins, backlash, expansion; the
 * real loader run on those bytes, so every such table it accepts), and any
 * SYNC period cycle_us the configuration accepts (100..1000000 us). Then any
 * number of frames as above: the thermal frames (thermal_cob_id + 0..4, any
 * DLC and payload: every INT16 reading, "no reading" included) fill the
 * sample and the one with the last input hands it to the thermal runtime
 * (abbe_thermal_update_q), each SYNC runs abbe_comp_step_thermal_q with the
 * model and its thermal state. The model is running when the frames start:
 * one SYNC after the load installs it (frames while it is still queued, and
 * a second load among the frames into the other slot, are not in this
 * harness: docs/proofs.md, "Not proven yet"). */
#include "__fc_builtin.h"

#include "abbe_can.h"

#if defined(PROOF_MODEL)
#include <string.h>

#include "any_scalars.h"

extern const uint8_t abbe_golden_thermal_blob[];
extern const uint32_t abbe_golden_thermal_blob_size;

#define PROOF_BLOB_SIZE 6656u /* abbe_golden_thermal_blob_size */
static unsigned char table[PROOF_BLOB_SIZE] __attribute__((aligned(8)));
#endif

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
#if defined(PROOF_MODEL)
    cfg.cycle_us = Frama_C_unsigned_int_interval(100u, 1000000u);
#endif
    if (abbe_can_node_init(&node, &cfg) != ABBE_CAN_OK) {
        return 1;
    }
#if defined(PROOF_MODEL)
    if (abbe_golden_thermal_blob_size != PROOF_BLOB_SIZE) {
        return 2;
    }
    memcpy(table, abbe_golden_thermal_blob, PROOF_BLOB_SIZE);
    any_scalars(table);
    if (abbe_can_node_load_model(&node, table, PROOF_BLOB_SIZE) != ABBE_CAN_OK) {
        return 3;
    }
#endif
    abbe_can_frame_t tx[ABBE_CAN_MAX_TX];
#if defined(PROOF_MODEL)
    /* a first SYNC: the queued model takes effect (its thermal state
     * starts), so every state of the loop below runs it (an interval
     * analysis would otherwise join "queued" with "running") */
    {
        abbe_can_frame_t sync;
        memset(&sync, 0, sizeof sync);
        sync.id = cfg.sync_cob_id;
        size_t n_tx = 0;
        if (abbe_can_node_rx(&node, &sync, tx, &n_tx) != ABBE_CAN_RX_SYNC) {
            return 4;
        }
    }
#endif
    int last = 0;
    while (Frama_C_interval(0, 1)) {
        abbe_can_frame_t rx;
        Frama_C_make_unknown((char *)&rx, sizeof rx);
        size_t n_tx = 0;
        last = abbe_can_node_rx(&node, &rx, tx, &n_tx);
    }
    return last;
}
