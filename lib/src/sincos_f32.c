/* abbe: sin and cos of a phase in single precision (see sincos_f32.h). */
#include "sincos_f32.h"

/* sqrt(1/2) = 0.70710678118654752, correctly rounded to float by the compiler */
const abbe_sincos_f32_table_t abbe_sincos_f32_table = {
    {0.002474437700584531f, -0.08074352145195007f, 0.7853981256484985f, -0.00032427161931991577f,
     0.01585409604012966f, -0.3084251284599304f, 1.0f, 0.0f},
    {0.0f, 1.0f, 0.70710678118654752f, 0.70710678118654752f, 1.0f, 0.0f, 0.70710678118654752f,
     -0.70710678118654752f, 0.0f, -1.0f, -0.70710678118654752f, -0.70710678118654752f, -1.0f, 0.0f,
     -0.70710678118654752f, 0.70710678118654752f},
};

void abbe_sincos_f32(uint32_t phase_q32, float *sin_out, float *cos_out)
{
    abbe_sincos_f32_inline(phase_q32, sin_out, cos_out);
}
