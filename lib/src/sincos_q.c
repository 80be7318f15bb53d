/* abbe: sin and cos of a phase in Q30, integer only (see sincos_q.h). */
#include "sincos_q.h"

void abbe_sincos_q30(uint32_t phase_q32, int32_t *sin_out, int32_t *cos_out)
{
    abbe_sincos_q30_inline(phase_q32, sin_out, cos_out);
}
