/* abbe CAN port: helpers shared by the port's sources. Not installed. */
#ifndef ABBE_CAN_INTERNAL_H
#define ABBE_CAN_INTERNAL_H

#include <stdint.h>

/* Round half away from zero and saturate to int32; NaN gives 0. */
int32_t abbe_can_round_sat(double v);

#endif /* ABBE_CAN_INTERNAL_H */
