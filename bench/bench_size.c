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
