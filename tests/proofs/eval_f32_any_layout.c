/* Eva harness: the float evaluation abbe_error_eval_f32 (eval_f32.c,
 * eval_f32_linear.h, terms_f32.c, kernel_f32.h, the extras) on a model of ANY
 * layout the loader accepts (tests/proofs/any_layout.h: every term mask,
 * trend degree, harmonic count and reversal row count, any scalars; the
 * header fields as in eval_q_any_layout.c, their float twins as
 * build_assembly computes them), the kernels run as they are (a float sum
 * has no undefined overflow; what is proven is no runtime error and nothing
 * non-finite). Coefficients (float): any value in [-2^31, 2^31] in every word
 * (the loader accepts a float twin only as its int32 converted, check_twins:
 * every accepted coefficient, the L1 caps' and the reversal rows' included;
 * [-2^27, 2^27], the union of the boxes of any_layout.h, until the five-axis
 * float caps proof, docs/proofs.md). Every finite position and
 * direction state, every temperature in [-10^6, 10^6] degC. The compensator's
 * float cycle is left to the golden-layout harnesses (eval_f32_<table>): with
 * it this harness cost 32 s of CPU instead of 2 (docs/proofs.md). */
#define PROOF_LAYOUT_COEF_UNION
#include "any_layout.h"

#include "abbe/comp.h"
#include "abbe/error.h"

static abbe_model_t model;
static abbe_comp_t comp;
static int32_t coef[ABBE_AXES][ANY_COEF_WORDS];
static float coef_f[ABBE_AXES][ANY_COEF_WORDS];

static float any_f32(void)
{
    return Frama_C_float_interval(-3.40282347e+38f, 3.40282347e+38f);
}

static void any_model(abbe_model_t *m)
{
    memset(m, 0, sizeof *m);
    m->features = Frama_C_unsigned_int_interval(0u, ABBE_FEATURE_ALL);
    m->version_major = 1u;
    m->version_minor = (uint16_t)Frama_C_unsigned_int_interval(0u, 1u);
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        m->reference_nm[j] = Frama_C_int_interval(INT32_MIN, INT32_MAX);
        m->tool_offset_nm[j] = Frama_C_int_interval(INT32_MIN, INT32_MAX);
        m->squareness_q36[j] = Frama_C_int_interval(-(1 << 28), 1 << 28);
        m->ref_half_nm[j] = m->reference_nm[j] >> 1;
        m->tool_half_nm[j] = (float)m->tool_offset_nm[j] * 0.5f;
        m->squareness_f[j] = (float)m->squareness_q36[j];
        any_axis(&m->axis[j], coef[j]);
        /*@ loop unroll 0; */
        for (unsigned i = 0; i < ANY_COEF_WORDS; i++) {
            coef_f[j][i] = Frama_C_float_interval(-2147483648.0f, 2147483648.0f);
        }
        m->axis[j].coef_f32 = (const uint8_t *)coef_f[j];
    }
}

int main(void)
{
    any_model(&model);
    abbe_input_f32_t in;
    abbe_error_f32_t out;
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        in.pos_mm[j] = any_f32();
        in.dir_state[j] = any_f32();
        in.temp_c[j] = Frama_C_float_interval(-1.0e6f, 1.0e6f);
    }
    (void)abbe_error_eval_f32(&model, &in, &out);
    return 0;
}
