/* abbe LinuxCNC port, load time: the HAL parameters turned into the
 * compensator's configuration, the port's start, and the table slots
 * (include/abbe_lcnc.h). What runs every servo period is abbe_lcnc.c.
 * C99, no heap, no I/O, no libm. */
#include <string.h>

#include "abbe_lcnc.h"
#include "abbe_lcnc_units.h"

/* A length parameter in mm as a positive int32 nm (at least 1). */
static int length_nm(double mm, int32_t *nm)
{
    if (!finite_d(mm) || !(mm > 0.0) || mm * NM_PER_MM > 2147483647.0) {
        return 0;
    }
    int64_t v = round_i64(mm * NM_PER_MM);
    *nm = v < 1 ? 1 : (int32_t)v;
    return 1;
}

/* A duration in s as a cycle count in [1, 65535] (0 s -> 1 cycle). */
static int duration_cycles(double s, long period_ns, uint16_t *cycles)
{
    if (!finite_d(s) || s < 0.0) {
        return 0;
    }
    double c = s * 1e9 / (double)period_ns;
    if (c > 65535.0) {
        return 0;
    }
    int64_t n = (int64_t)c;
    if ((double)n < c) {
        n++; /* ceil: a fade never runs shorter than asked */
    }
    *cycles = (uint16_t)(n < 1 ? 1 : n);
    return 1;
}

void abbe_lcnc_default_params(abbe_lcnc_params_t *params)
{
    if (params == NULL) {
        return;
    }
    memset(params, 0, sizeof *params);
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        params->warn_mm[j] = 0.05;
        params->limit_mm[j] = 0.1;
        params->rate_mm_per_s[j] = 1.0;
        params->sign[j] = 1;
    }
    params->fade_s = 0.5;
    params->stale_s = 0.01;
    params->dir_deadband_mm = 0.0005;
    params->lead_periods = 2.0;
    params->machine_unit_mm = 1.0;
    params->kins_identity = 0;
    params->kins_tcp = 1;
    params->thermal_sample_s = 1.0;
}

abbe_status_t abbe_lcnc_params_to_config(const abbe_lcnc_params_t *params, long period_ns,
                                         abbe_comp_config_t *cfg)
{
    if (params == NULL || cfg == NULL || period_ns <= 0) {
        return ABBE_E_ARG;
    }
    abbe_comp_config_t c;
    memset(&c, 0, sizeof c);
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        double rate_mm_per_cycle = params->rate_mm_per_s[j] * (double)period_ns * 1e-9;
        if (!length_nm(params->warn_mm[j], &c.warn_nm[j]) ||
            !length_nm(params->limit_mm[j], &c.limit_nm[j]) || c.limit_nm[j] < c.warn_nm[j] ||
            !finite_d(params->rate_mm_per_s[j]) || !(params->rate_mm_per_s[j] > 0.0) ||
            !length_nm(rate_mm_per_cycle, &c.rate_nm_per_cycle[j]) ||
            (params->sign[j] != 1 && params->sign[j] != -1)) {
            return ABBE_E_ARG;
        }
        c.axis_sign[j] = (int8_t)params->sign[j];
    }
    if (!duration_cycles(params->fade_s, period_ns, &c.fade_cycles) ||
        !duration_cycles(params->stale_s, period_ns, &c.stale_cycles) ||
        !finite_d(params->dir_deadband_mm) || params->dir_deadband_mm < 0.0 ||
        params->dir_deadband_mm > 1000.0 || !finite_d(params->lead_periods) ||
        params->lead_periods < 0.0 || params->lead_periods > 100.0 ||
        !finite_d(params->machine_unit_mm) ||
        !(params->machine_unit_mm > 0.0) || params->kins_identity == params->kins_tcp ||
        !finite_d(params->thermal_sample_s) || params->thermal_sample_s < 0.001 ||
        params->thermal_sample_s > 3600.0) {
        return ABBE_E_ARG;
    }
    *cfg = c;
    return ABBE_OK;
}

abbe_status_t abbe_lcnc_init(abbe_lcnc_t *port, abbe_lcnc_variant_t variant,
                             const abbe_lcnc_params_t *params, long period_ns)
{
    if (port == NULL || params == NULL ||
        (variant != ABBE_LCNC_VARIANT_Q && variant != ABBE_LCNC_VARIANT_F32)) {
        return ABBE_E_ARG;
    }
    abbe_comp_config_t cfg;
    if (abbe_lcnc_params_to_config(params, period_ns, &cfg) != ABBE_OK) {
        return ABBE_E_ARG;
    }
    memset(port, 0, sizeof *port);
    if (abbe_comp_init(&port->comp, &cfg, NULL) != ABBE_OK) {
        return ABBE_E_ARG;
    }
    port->variant = variant;
    port->cfg = cfg;
    port->deadband_nm = (int32_t)round_i64(params->dir_deadband_mm * NM_PER_MM);
    port->lead_periods = params->lead_periods;
    port->eoffset_scale = 1.0 / (NM_PER_MM * params->machine_unit_mm);
    port->kins_identity = params->kins_identity;
    port->kins_tcp = params->kins_tcp;
    memcpy(&port->params_seen, params, sizeof port->params_seen);
    port->period_seen_ns = period_ns;
    port->th_table = -1;
    return ABBE_OK;
}

/* Load blob into *slot: a five-axis table as one, a 3-axis table through
 * abbe_model_load into its linear member (the 3-axis path stays exactly the
 * 3-axis library's). *kind: ABBE_KIN_*. */
static abbe_status_t load_table(abbe_five_model_t *slot, abbe_thermal_model_t *th, const void *blob, size_t size,
                                uint32_t *kind)
{
    abbe_status_t st = abbe_five_model_load(slot, blob, size);
    if (st == ABBE_E_VERSION_MINOR) {
        /* format 1.3: a 3-axis table with a thermal block (abbe_thermal_load:
         * every check of abbe_model_load, then the block's) */
        abbe_thermal_model_t scratch;
        memset(slot, 0, sizeof *slot);
        *kind = ABBE_KIN_NONE;
        return abbe_thermal_load(&slot->linear, th != NULL ? th : &scratch, blob, size);
    }
    if (st != ABBE_OK) {
        return st;
    }
    if (th != NULL) {
        memset(th, 0, sizeof *th); /* no thermal block */
    }
    *kind = abbe_five_model_kind(slot);
    return *kind == ABBE_KIN_NONE ? abbe_model_load(&slot->linear, blob, size) : ABBE_OK;
}

uint32_t abbe_lcnc_blob_kind(const void *blob, size_t size)
{
    abbe_five_model_t m;
    uint32_t kind = 0;
    return (blob != NULL && load_table(&m, NULL, blob, size, &kind) == ABBE_OK) ? kind : 0xFFFFFFFFu;
}

abbe_status_t abbe_lcnc_add_table(abbe_lcnc_t *port, const void *blob, size_t size)
{
    if (port == NULL || blob == NULL || port->n_tables >= ABBE_LCNC_MAX_TABLES) {
        return ABBE_E_ARG;
    }
    abbe_five_model_t m;
    uint32_t kind = 0;
    abbe_status_t st = load_table(&m, NULL, blob, size, &kind);
    if (st != ABBE_OK) {
        return st;
    }
    if (port->n_tables > 0u && kind != port->kind) {
        return ABBE_E_ARG; /* the pins mean axis or joint positions: one kind for all tables */
    }
    (void)load_table(&port->model[port->n_tables], &port->thermal[port->n_tables], blob, size,
                     &kind); /* a view: valid as m was */
    if (port->n_tables == 0u) {
        port->kind = kind;
        (void)abbe_comp_swap_model(&port->comp, &port->model[0].linear); /* runs from the first step */
        port->active = 0;
    }
    port->n_tables++;
    return ABBE_OK;
}

uint32_t abbe_lcnc_kind(const abbe_lcnc_t *port)
{
    return port != NULL ? port->kind : 0u;
}

unsigned abbe_lcnc_table_count(const abbe_lcnc_t *port)
{
    return port != NULL ? port->n_tables : 0u;
}

uint32_t abbe_lcnc_table_crc(const abbe_lcnc_t *port, unsigned i)
{
    return (port != NULL && i < port->n_tables) ? abbe_model_crc(&port->model[i].linear) : 0u;
}
