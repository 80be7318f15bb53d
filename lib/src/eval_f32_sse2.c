/* abbe: the x86-64 single-precision core for every x86-64 (SSE2), and the
 * dispatch to its x86-64-v3 build (eval_f32_avx2.c) where the CPU has AVX2
 * and FMA (abbe_model_load() sets model->simd). */
#include "eval_f32_x86.h"

#if defined(ABBE_F32_SSE2)
/* Out of line, so that the dispatcher below is two tail calls (no frame). */
#if defined(__GNUC__)
__attribute__((noinline))
#endif
static abbe_status_t eval_f32_sse2(const abbe_model_t *m, const abbe_input_f32_t *in, abbe_error_f32_t *out)
{
    return eval_f32_x86(m, in, out);
}

abbe_status_t abbe_eval_f32_core(const abbe_model_t *m, const abbe_input_f32_t *in, abbe_error_f32_t *out)
{
#if defined(ABBE_X86_V3)
    if (m->simd == ABBE_SIMD_X86_V3) {
        return abbe_eval_f32_core_avx2(m, in, out);
    }
#endif
    return eval_f32_sse2(m, in, out);
}

#if defined(ABBE_X86_V3)
uint8_t abbe_simd_level(void)
{
    return (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) ? ABBE_SIMD_X86_V3 : 0u;
}
#endif
#endif
