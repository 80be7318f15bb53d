/* abbe: the x86-64 single-precision core compiled for x86-64-v3 (AVX2, FMA:
 * three-operand forms and fused multiply-adds; lib/CMakeLists.txt sets the
 * flags for this file only). Called only where the CPU has both
 * (abbe_simd_level, eval_f32_sse2.c). */
#include "eval_f32_x86.h"

#if defined(ABBE_F32_SSE2) && defined(ABBE_X86_V3)
abbe_status_t abbe_eval_f32_core_avx2(const abbe_model_t *m, const abbe_input_f32_t *in, abbe_error_f32_t *out)
{
    return eval_f32_x86(m, in, out);
}
#endif
