/* abbe: sin and cos of a phase in single precision (see sincos_f32.h). */
#include "sincos_f32.h"

#define ABBE_R2_F32 0.70710678118654752f
const abbe_sincos_f32_table_t abbe_sincos_f32_table = {
    {0.002474437700584531f, -0.08074352145195007f, 0.7853981256484985f, -0.00032427161931991577f,
     0.01585409604012966f, -0.3084251284599304f, 1.0f, 0.0f},
    {0.0f, 1.0f, ABBE_R2_F32, ABBE_R2_F32, 1.0f, 0.0f, ABBE_R2_F32, -ABBE_R2_F32, 0.0f, -1.0f, -ABBE_R2_F32,
     -ABBE_R2_F32, -1.0f, 0.0f, -ABBE_R2_F32, ABBE_R2_F32},
};
#undef ABBE_R2_F32

void abbe_sincos_f32(uint32_t phase_q32, float *sin_out, float *cos_out)
{
    abbe_sincos_f32_inline(phase_q32, sin_out, cos_out);
}
