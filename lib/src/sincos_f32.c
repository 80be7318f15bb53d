/* abbe: sin and cos of a phase in single precision (see sincos_f32.h). */
#include "sincos_f32.h"

void abbe_sincos_f32(uint32_t phase_q32, float *sin_out, float *cos_out)
{
    abbe_sincos_f32_inline(phase_q32, sin_out, cos_out);
}
