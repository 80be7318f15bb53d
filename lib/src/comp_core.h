/* abbe: the compensator's variant-independent cycle (comp.c), used by
 * comp_q.c and comp_f32.c. Not installed. */
#ifndef ABBE_COMP_CORE_H
#define ABBE_COMP_CORE_H

#include "internal.h"

/* Start of a cycle: take a queued model into use. Returns the cycle's flags. */
uint32_t abbe_comp_begin(abbe_comp_t *comp);

/* Ramp the backlash direction states by this cycle's motion (valid input only). */
void abbe_comp_track_direction(abbe_comp_t *comp, const int32_t pos_nm[ABBE_AXES],
                               const int8_t dir[ABBE_AXES]);

/* End of a cycle: watchdog, limits, fades, rate limit, output. input_ok: the
 * input was fresh and finite. error_nm: this cycle's model error, or NULL when
 * there was none (bad input or no model): the last target is then held while
 * the gains fade. */
void abbe_comp_finish(abbe_comp_t *comp, int input_ok, const int32_t *error_nm, uint32_t flags,
                      uint8_t axis_fault_mask, abbe_comp_output_t *out);

/* um -> nm, rounded, saturated (ABBE_FLAG_SATURATED): comp_f32.c. */
int32_t abbe_comp_um_to_nm(float um, uint32_t *flags);

/* The five-axis model the compensator runs, or NULL for a 3-axis one (comp_five.c). */
const abbe_five_model_t *abbe_comp_five_model(const abbe_comp_t *comp);

#endif /* ABBE_COMP_CORE_H */
