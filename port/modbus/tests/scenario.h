/* The end-to-end scenario shared by the TCP and RTU tests: configure the
 * compensator over Modbus, upload a table, stream positions and compare every
 * cycle's outputs with abbe_comp_step_q() run here on the same inputs. */
#ifndef ABBE_MODBUS_SCENARIO_H
#define ABBE_MODBUS_SCENARIO_H

#include <stddef.h>
#include <stdint.h>

#include <modbus.h>

#include "abbe/abbe.h"

/* The limits the scenario writes (CT registers) and uses locally. */
abbe_comp_config_t scn_config(void);

/* Write scn_config() into the CT registers (compensator must be off). 0 or -1. */
int scn_configure(modbus_t *ctx, int wo);

/* Upload blob and check the server reports it validated and queued with the
 * table's own CRC. Returns 0, or -1 (errno from libmodbus, or EPROTO for a
 * wrong report). */
int scn_upload(modbus_t *ctx, const uint8_t *blob, size_t size, int wo);

/* Enable and run ncycles cycles with FC23 (write inputs incl. IN_CYCLE, read
 * outputs), comparing with a local compensator that has the same model and
 * limits. Returns the number of cycles that differ (0 = pass), -1 on a
 * transport error. *moved receives the largest |correction| seen, nm. */
int scn_stream_compare(modbus_t *ctx, const uint8_t *blob, size_t size, int wo, int ncycles,
                       int32_t *moved);

#endif /* ABBE_MODBUS_SCENARIO_H */
