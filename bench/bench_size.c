/* Minimal users of the library, one per configuration (SIZE_LOAD,
 * SIZE_EVAL_F32, SIZE_EVAL_Q, SIZE_COMP_F32, SIZE_COMP_Q): their link maps
 * tell how much flash and RAM the library itself takes in each use.
 * The blob comes from a pointer the compiler cannot see through. */
#include <stddef.h>
#include <stdint.h>

#include "abbe/abbe.h"

const uint8_t *volatile bench_blob;
volatile size_t bench_blob_size;
volatile int32_t bench_sink;

#if defined(SIZE_FIVE_F32) || defined(SIZE_FIVE_Q)
/* Five-axis: load + five-axis evaluation + the compensator's five-axis cycle. */
int main(void)
{
    abbe_five_model_t model;
    abbe_status_t st = abbe_five_model_load(&model, bench_blob, bench_blob_size);
    abbe_comp_config_t cfg = {{1000, 1000, 1000}, {2000, 2000, 2000}, {10, 10, 10}, 4, 4, {1, 1, 1}};
    abbe_comp_t comp;
    abbe_comp_output5_t out;
    abbe_comp_init(&comp, &cfg, NULL);
    abbe_comp_swap_five_model(&comp, &model);
    abbe_comp_enable(&comp);
#if defined(SIZE_FIVE_F32)
    abbe_five_input_f32_t ein = {{1.0f, 2.0f, 3.0f}, {10.0f, 20.0f}, {0.0f, 0.0f, 0.0f}, {20.0f, 20.0f, 20.0f}};
    abbe_five_error_f32_t eout;
    st = abbe_five_error_eval_f32(&model, &ein, &eout);
    abbe_comp_input5_f32_t in = {{{1.0f, 2.0f, 3.0f}, {20.0f, 20.0f, 20.0f}, {0, 0, 0}, 1, 0}, {10.0f, 20.0f}};
    st = abbe_comp_step5_f32(&comp, &in, &out);
    bench_sink = (int32_t)eout.flags;
#else
    abbe_five_input_q_t ein = {{1, 2, 3}, {10, 20}, {0, 0, 0}, {20000, 20000, 20000}};
    abbe_five_error_q_t eout;
    st = abbe_five_error_eval_q(&model, &ein, &eout);
    abbe_comp_input5_q_t in = {{{1, 2, 3}, {20000, 20000, 20000}, {0, 0, 0}, 1, 0}, {10, 20}};
    st = abbe_comp_step5_q(&comp, &in, &out);
    bench_sink = eout.error_nm[0];
#endif
    bench_sink += out.lin.corr_nm[0];
    return (int)st;
}
#else
int main(void)
{
    abbe_model_t model;
    abbe_status_t st = abbe_model_load(&model, bench_blob, bench_blob_size);
#if defined(SIZE_EVAL_F32)
    abbe_input_f32_t in = {{1.0f, 2.0f, 3.0f}, {0.0f, 0.0f, 0.0f}, {20.0f, 20.0f, 20.0f}};
    abbe_error_f32_t out;
    st = abbe_error_eval_f32(&model, &in, &out);
    bench_sink = (int32_t)out.flags;
#elif defined(SIZE_EVAL_Q)
    abbe_input_q_t in = {{1, 2, 3}, {0, 0, 0}, {20000, 20000, 20000}};
    abbe_error_q_t out;
    st = abbe_error_eval_q(&model, &in, &out);
    bench_sink = out.error_nm[0];
#elif defined(SIZE_COMP_F32) || defined(SIZE_COMP_Q)
    abbe_comp_config_t cfg = {{1000, 1000, 1000}, {2000, 2000, 2000}, {10, 10, 10}, 4, 4, {1, 1, 1}};
    abbe_comp_t comp;
    abbe_comp_output_t out;
    abbe_comp_init(&comp, &cfg, &model);
    abbe_comp_enable(&comp);
#if defined(SIZE_COMP_F32)
    abbe_comp_input_f32_t in = {{1.0f, 2.0f, 3.0f}, {20.0f, 20.0f, 20.0f}, {0, 0, 0}, 1, 0};
    st = abbe_comp_step_f32(&comp, &in, &out);
#else
    abbe_comp_input_q_t in = {{1, 2, 3}, {20000, 20000, 20000}, {0, 0, 0}, 1, 0};
    st = abbe_comp_step_q(&comp, &in, &out);
#endif
    bench_sink = out.corr_nm[0];
#endif
    return (int)st;
}
#endif
