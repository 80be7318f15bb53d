/* Any input value of the Eva harnesses (comp5_cycles.h, eval_five_f32.c):
 * any_i32 every int32; any_f32 every finite float32, or with PROOF_NONFINITE
 * any 32 bits (NaN and the infinities included: those harnesses run with
 * -warn-special-float none); any_temp a temperature in [-10^6, 10^6] degC
 * (docs/proofs.md: beyond, the refusal rests on a bit test), or any 32 bits. */
#ifndef PROOF_ANY_INPUTS_H
#define PROOF_ANY_INPUTS_H

#include "__fc_builtin.h"
#include <stdint.h>
#include <string.h>

static inline int32_t any_i32(void)
{
    return Frama_C_int_interval(INT32_MIN, INT32_MAX);
}

#if defined(PROOF_NONFINITE)
/* any float32, NaN and the infinities included: any 32 bits */
static inline float any_f32(void)
{
    uint32_t bits = Frama_C_unsigned_int_interval(0u, UINT32_MAX);
    float f;
    memcpy(&f, &bits, sizeof f);
    return f;
}
static inline float any_temp(void)
{
    return any_f32();
}
#else
/* any finite float32 */
static inline float any_f32(void)
{
    return Frama_C_float_interval(-3.40282347e+38f, 3.40282347e+38f);
}
static inline float any_temp(void)
{
    return Frama_C_float_interval(-1.0e6f, 1.0e6f);
}
#endif

#endif /* PROOF_ANY_INPUTS_H */
