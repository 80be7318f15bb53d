/* The Modbus harnesses' model of the abbe library functions the register map
 * calls that read a table's content (docs/proofs.md, "Modbus"): the table
 * loader, the compensator's cycle and the thermal runtime. Each checks the
 * pointers and the initialised inputs the real function reads (Eva proves
 * these assertions at every call) and returns any value of the range the
 * real function documents, so the register map is proven for every table
 * and every evaluation result, not for one. The real functions are proven
 * on their own harnesses (load3, eval_q_*, eval_f32_*); the format 1.3
 * loader (abbe_thermal_load) is not yet (docs/proofs.md, "Not proven yet").
 * The library's plain bookkeeping (comp.c: init, enable, swap, stats;
 * thermal.c; the model accessors; crc32.c) runs as the real code. */
#include <string.h>

#include "__fc_builtin.h"

#include "abbe/comp.h"
#include "abbe/thermal.h"
#include "comp_core.h"

/* Validates blob[0 .. size) into *model and *thermal; on a refusal (any
 * status) leaves both untouched. */
abbe_status_t abbe_thermal_load(abbe_model_t *model, abbe_thermal_model_t *thermal, const void *blob, size_t size)
{
    //@ assert model_valid: \valid(model);
    //@ assert thermal_valid: \valid(thermal);
    //@ assert blob_valid: size > 0 ==> \valid_read((const unsigned char *)blob + (0 .. size - 1));
    if (Frama_C_nondet(0, 1)) {
        return (abbe_status_t)Frama_C_interval(-20, -1);
    }
    memset(model, 0, sizeof *model);
    model->crc = Frama_C_unsigned_int_interval(0u, 0xFFFFFFFFu);
    model->size = (uint32_t)size;
    model->features = Frama_C_unsigned_int_interval(0u, 0xFFFFFFFFu);
    memset(thermal, 0, sizeof *thermal);
    thermal->n_inputs = (uint8_t)Frama_C_unsigned_int_interval(0u, ABBE_THERMAL_MAX_INPUTS);
    thermal->n_channels = (uint8_t)Frama_C_unsigned_int_interval(0u, ABBE_THERMAL_MAX_CHANNELS);
    Frama_C_make_unknown((char *)thermal->kind, sizeof thermal->kind);
    return ABBE_OK;
}

unsigned abbe_thermal_n_inputs(const abbe_thermal_model_t *thermal)
{
    return thermal != NULL ? thermal->n_inputs : 0u;
}

abbe_status_t abbe_thermal_init_q(abbe_thermal_state_t *st, const abbe_thermal_model_t *thermal, uint32_t period_us)
{
    //@ assert st_valid: \valid(st);
    //@ assert model_read: \valid_read(thermal);
    (void)period_us;
    memset(st, 0, sizeof *st);
    st->model = thermal;
    return ABBE_OK;
}

/* x[0 .. n_inputs) read (the model's input count, at most 17). */
abbe_status_t abbe_thermal_update_q(abbe_thermal_state_t *st, const int32_t x_milli[], uint32_t valid_mask,
                                    uint32_t dt_ms)
{
    //@ assert st_valid: \valid(st);
    //@ assert inputs_read: \valid_read(x_milli + (0 .. ABBE_THERMAL_MAX_INPUTS - 1));
    //@ assert inputs_set: \initialized(x_milli + (0 .. ABBE_THERMAL_MAX_INPUTS - 1));
    (void)valid_mask;
    (void)dt_ms;
    st->flags = Frama_C_unsigned_int_interval(0u, 0xFFFFFFFFu);
    st->events = Frama_C_unsigned_int_interval(0u, 0xFFFFFFFFu);
    st->input_fault = Frama_C_unsigned_int_interval(0u, 0xFFFFFFFFu);
    return ABBE_OK;
}

unsigned abbe_thermal_channels_q(const abbe_thermal_state_t *st, int32_t y[ABBE_THERMAL_MAX_CHANNELS])
{
    //@ assert st_read: \valid_read(st);
    //@ assert out_valid: \valid(y + (0 .. ABBE_THERMAL_MAX_CHANNELS - 1));
    unsigned n = Frama_C_unsigned_int_interval(0u, ABBE_THERMAL_MAX_CHANNELS);
    for (unsigned c = 0; c < n; c++) {
        y[c] = Frama_C_int_interval(INT32_MIN, INT32_MAX);
    }
    return n;
}

/* One cycle: the real bookkeeping (abbe_comp_begin: the queued model swapped
 * in, the counters), then any output. */
abbe_status_t abbe_comp_step_thermal_q(abbe_comp_t *comp, abbe_thermal_state_t *thermal,
                                       const abbe_comp_input_q_t *in, abbe_comp_output_t *out)
{
    //@ assert comp_valid: \valid(comp);
    //@ assert in_read: \valid_read(in) && \initialized(in);
    //@ assert out_valid: \valid(out);
    //@ assert thermal_valid: thermal == \null || \valid(thermal);
    (void)abbe_comp_begin(comp);
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        out->corr_nm[j] = Frama_C_int_interval(INT32_MIN, INT32_MAX);
        out->target_nm[j] = Frama_C_int_interval(INT32_MIN, INT32_MAX);
    }
    out->flags = Frama_C_unsigned_int_interval(0u, 0xFFFFFFFFu);
    out->state = (abbe_comp_state_t)Frama_C_interval(ABBE_COMP_OFF, ABBE_COMP_FAULT);
    return ABBE_OK;
}
