/* abbe: the x86-64 single-precision core compiled for x86-64-v3 (AVX2, FMA:
 * three-operand forms and fused multiply-adds; lib/CMakeLists.txt sets the
 * flags for this file only). Called only where the CPU has both
 * (abbe_simd_level, eval_f32_sse2.c). */
#include "eval_f32_x86.h"

#if defined(ABBE_F32_SSE2) && defined(ABBE_X86_V3)
abbe_status_t abbe_eval_f32_core_avx2(const abbe_model_t *m, const float pos_mm[ABBE_AXES],
                                      const float dir_state[ABBE_AXES], const float temp_c[ABBE_AXES],
                                      float error_um[ABBE_AXES], uint32_t *flags_out)
{
    return eval_f32_x86(m, pos_mm, dir_state, temp_c, error_um, flags_out);
}
#endif
