/* The hypotheses of the Eva proofs: ACSL assertions in lib/src that an
 * interval analysis cannot decide (a value followed through its bits), each
 * checked here on every one of its 2^32 inputs by running the library's own
 * code. scripts/prove.sh compiles this and runs each check next to the Eva
 * harnesses; the assertions may stay unknown to Eva only if these pass. The
 * run is sound for the C semantics because the Eva harnesses prove the code
 * involved free of undefined behaviour (harness 'sincos'; the clamp is
 * unsigned arithmetic and memcpy only).
 *   hypotheses sincos_range: abbe_sincos_q30_pair gives |sin|, |cos| <= 2^30
 *       for every phase (internal.h, abbe_q30_of_bits);
 *   hypotheses mm_clamped: abbe_mm_clamp_bits gives a finite float in
 *       [-2147, 2147] for every float, NaN and infinities included
 *       (internal.h, abbe_mm_to_nm_inline), and abbe_mm_to_nm_inline, which
 *       the float evaluations call on each position, reports exactly the NaNs
 *       and infinities (the evaluation refuses them: ABBE_E_INPUT);
 *   hypotheses f32_finite: abbe_f32_nonfinite is false only for a finite
 *       float (thermal_f32.c, the period of abbe_thermal_init_f32).
 * Exit 1 naming the first input that breaks one; 2 for a bad argument. */
#include <inttypes.h>
#include <stdio.h>
#include <string.h>

#include "internal.h"

static int sincos_range(void)
{
    uint32_t phase = 0u;
    int32_t lo = 0, hi = 0;
    do {
        const uint64_t pair = abbe_sincos_q30_pair(phase);
        const int32_t s = abbe_u32_to_i32((uint32_t)pair);
        const int32_t c = abbe_u32_to_i32((uint32_t)(pair >> 32));
        if (s < -ABBE_Q30_ONE || s > ABBE_Q30_ONE || c < -ABBE_Q30_ONE || c > ABBE_Q30_ONE) {
            printf("sincos_range: phase 0x%08" PRIx32 ": sin %" PRId32 ", cos %" PRId32 " beyond +/-2^30\n", phase, s,
                   c);
            return 1;
        }
        lo = s < lo ? s : lo;
        lo = c < lo ? c : lo;
        hi = s > hi ? s : hi;
        hi = c > hi ? c : hi;
        phase++;
    } while (phase != 0u);
    printf("sincos_range: all 2^32 phases, sin and cos in [%" PRId32 ", %" PRId32 "]\n", lo, hi);
    return 0;
}

static int mm_clamped(void)
{
    uint32_t bits = 0u;
    uint32_t n_over = 0u;
    do {
        float mm;
        memcpy(&mm, &bits, sizeof mm);
        const uint32_t over = (uint32_t)((bits & 0x7FFFFFFFu) > 0x45063000u);
        const uint32_t cbits = abbe_mm_clamp_bits(bits);
        float c;
        memcpy(&c, &cbits, sizeof c);
        /* finite by its bits (no float compare of a NaN), then the range */
        if (abbe_f32_bits_nonfinite(cbits) || !(c >= -2147.0f && c <= 2147.0f) ) {
            printf("mm_clamped: input bits 0x%08" PRIx32 ": clamped to bits 0x%08" PRIx32 "\n", bits, cbits);
            return 1;
        }
        /* and the evaluation's refusal test: nonzero exactly for NaN and Inf */
        int32_t nm;
        uint32_t flags = 0u;
        const uint32_t refused = abbe_mm_to_nm_inline(mm, &nm, &flags);
        if (refused != (uint32_t)abbe_f32_bits_nonfinite(bits)) {
            printf("mm_clamped: input bits 0x%08" PRIx32 ": abbe_mm_to_nm_inline returns %" PRIu32 "\n", bits, refused);
            return 1;
        }
        n_over += over;
        bits++;
    } while (bits != 0u);
    printf("mm_clamped: all 2^32 floats clamped into [-2147, 2147] (%" PRIu32 " of them beyond)\n", n_over);
    return 0;
}

/* f32_finite: abbe_f32_nonfinite (the library's test of a float on its bits)
 * is false only for a finite float: a float minus itself is 0 exactly when it
 * is finite (NaN - NaN and inf - inf are NaN). */
static int f32_finite(void)
{
    uint32_t bits = 0u;
    do {
        float f;
        memcpy(&f, &bits, sizeof f);
        volatile float g = f; /* the subtraction made at run time, not folded */
        const int finite = (g - g) == 0.0f;
        if (abbe_f32_nonfinite(f) == finite) {
            printf("f32_finite: bits 0x%08" PRIx32 ": abbe_f32_nonfinite %d for a %s float\n", bits,
                   abbe_f32_nonfinite(f), finite ? "finite" : "non-finite");
            return 1;
        }
        bits++;
    } while (bits != 0u);
    printf("f32_finite: abbe_f32_nonfinite is true exactly for the 2^32 floats' NaNs and infinities\n");
    return 0;
}

int main(int argc, char **argv)
{
    if (argc == 2 && strcmp(argv[1], "sincos_range") == 0) {
        return sincos_range();
    }
    if (argc == 2 && strcmp(argv[1], "mm_clamped") == 0) {
        return mm_clamped();
    }
    if (argc == 2 && strcmp(argv[1], "f32_finite") == 0) {
        return f32_finite();
    }
    fprintf(stderr, "usage: %s sincos_range|mm_clamped|f32_finite\n", argv[0]);
    return 2;
}
