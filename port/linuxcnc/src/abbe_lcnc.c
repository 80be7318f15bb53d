/* abbe LinuxCNC port, every servo period: enable logic, lead, backlash
 * direction, the thermal block's sampling, the compensator step and the
 * external-offset counts around abbe_comp_t (include/abbe_lcnc.h). The load
 * time (parameters, table slots) is abbe_lcnc_setup.c, the five-axis frames
 * abbe_lcnc_five.c. C99, no heap, no I/O, no libm. */
#include <string.h>

#include "abbe_lcnc.h"
#include "abbe_lcnc_five.h"
#include "abbe_lcnc_units.h"

/* mm -> nm, rounded, clamped to +/-(2^31 - 1) nm (the library clamps to the
 * table's travel anyway). x must be finite. */
static int32_t mm_to_nm(double mm)
{
    double nm = mm * NM_PER_MM;
    if (nm >= 2147483647.0) {
        return INT32_MAX;
    }
    if (nm <= -2147483647.0) {
        return -INT32_MAX;
    }
    return (int32_t)round_i64(nm);
}

/* deg C -> m deg C, rounded, clamped to +/-2e6 deg C. c must be finite. */
static int32_t c_to_mdegc(double c)
{
    double clamped = c > 2e6 ? 2e6 : (c < -2e6 ? -2e6 : c);
    return (int32_t)round_i64(clamped * 1000.0);
}

/* Parameters or period changed: convert and apply without touching the state. */
static void follow_params(abbe_lcnc_t *port, const abbe_lcnc_params_t *params, long period_ns)
{
    if (period_ns == port->period_seen_ns &&
        memcmp(params, &port->params_seen, sizeof *params) == 0) {
        return;
    }
    memcpy(&port->params_seen, params, sizeof port->params_seen);
    port->period_seen_ns = period_ns;
    abbe_comp_config_t cfg;
    if (abbe_lcnc_params_to_config(params, period_ns, &cfg) == ABBE_OK &&
        abbe_comp_set_config(&port->comp, &cfg) == ABBE_OK) {
        port->cfg = cfg;
        port->deadband_nm = (int32_t)round_i64(params->dir_deadband_mm * NM_PER_MM);
        port->lead_periods = params->lead_periods;
        port->eoffset_scale = 1.0 / (NM_PER_MM * params->machine_unit_mm);
        port->kins_identity = params->kins_identity;
        port->kins_tcp = params->kins_tcp;
        port->params_bad = 0;
    } else {
        port->params_bad = 1;
        port->config_errors++;
    }
}

/* Backlash direction with hysteresis: the direction turns once the axis has
 * moved back by more than the deadband from its furthest point; standing
 * still keeps it. Before the first move it is 0. */
static void follow_direction(abbe_lcnc_t *port, const int32_t pos_nm[ABBE_AXES], int32_t deadband_nm)
{
    if (!port->have_anchor) {
        for (unsigned j = 0; j < ABBE_AXES; j++) {
            port->anchor_nm[j] = pos_nm[j];
            port->dir[j] = 0;
        }
        port->have_anchor = 1;
        return;
    }
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        int64_t d = (int64_t)pos_nm[j] - port->anchor_nm[j];
        int8_t dir = port->dir[j];
        if ((dir > 0 && d > 0) || (dir < 0 && d < 0)) {
            port->anchor_nm[j] = pos_nm[j]; /* further in the same direction */
        } else if (d > deadband_nm) {
            port->dir[j] = 1;
            port->anchor_nm[j] = pos_nm[j];
        } else if (d < -(int64_t)deadband_nm) {
            port->dir[j] = -1;
            port->anchor_nm[j] = pos_nm[j];
        }
    }
}

/* Replace pos_nm (and the angles) by the position lead_periods ahead, from
 * this period's motion: p + round(lead * (p - p_previous)), clamped to int32;
 * angles a + lead * (a - a_previous). */
static void lead(abbe_lcnc_t *port, int32_t pos_nm[ABBE_AXES], double angle_deg[ABBE_ROTARY_AXES])
{
    for (unsigned r = 0; r < ABBE_ROTARY_AXES; r++) {
        double a = angle_deg[r];
        if (port->have_last) {
            angle_deg[r] = a + port->lead_periods * (a - port->last_angle_deg[r]);
        }
        port->last_angle_deg[r] = a;
    }
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        int32_t p = pos_nm[j];
        if (port->have_last) {
            double ahead = port->lead_periods * (double)((int64_t)p - port->last_pos_nm[j]);
            if (ahead > 4294967294.0) {
                ahead = 4294967294.0;
            } else if (ahead < -4294967294.0) {
                ahead = -4294967294.0;
            }
            int64_t q = (int64_t)p + round_i64(ahead);
            pos_nm[j] = q > INT32_MAX ? INT32_MAX : (q < -INT32_MAX ? -INT32_MAX : (int32_t)q);
        }
        port->last_pos_nm[j] = p;
    }
    port->have_last = 1;
}

static int running_index(const abbe_lcnc_t *port)
{
    const abbe_model_t *m = abbe_comp_model(&port->comp);
    for (unsigned i = 0; i < port->n_tables; i++) {
        if (m == &port->model[i].linear) {
            return (int)i;
        }
    }
    return -1;
}

static int32_t u32_to_i32(uint32_t u)
{
    int32_t v;
    memcpy(&v, &u, sizeof v);
    return v;
}

void abbe_lcnc_step(abbe_lcnc_t *port, const abbe_lcnc_params_t *params, long period_ns,
                    const abbe_lcnc_input_t *in, abbe_lcnc_output_t *out)
{
    if (port == NULL || params == NULL || in == NULL || out == NULL) {
        return;
    }
    uint32_t port_flags = 0;
    follow_params(port, params, period_ns);
    if (port->params_bad) {
        port_flags |= ABBE_LCNC_FLAG_CONFIG;
    }

    /* LinuxCNC's side of last cycle: did it take the change written then?
     * Its accept condition and its machine-on reset are visible on
     * motion.motion-enabled / motion.is-all-homed from the motion run that
     * read our counts (whichever side of motion-controller this runs on). */
    int accepting = in->machine_on && in->homed;
    if (in->machine_on && !port->prev_machine_on) {
        for (unsigned j = 0; j < ABBE_AXES; j++) {
            port->accepted_nm[j] = 0; /* motion zeroes its register at machine-on */
        }
    }
    port->prev_machine_on = in->machine_on;
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        if (accepting) {
            port->accepted_nm[j] += port->pending_nm[j];
        }
        port->pending_nm[j] = 0;
    }
    if (!accepting) {
        port_flags |= ABBE_LCNC_FLAG_HOLD;
    }

    /* Table selection: a pointer swap at the start of the next library step. */
    if (in->table_select != port->active) {
        if (in->table_select >= 0 && (unsigned)in->table_select < port->n_tables) {
            (void)abbe_comp_swap_model(&port->comp, &port->model[in->table_select].linear);
            port->active = in->table_select;
        } else {
            port_flags |= ABBE_LCNC_FLAG_TABLE_SELECT;
        }
    }

    /* Enable logic: reset clears a latched fault (and disables); the level of
     * enable && homed && machine-on then decides. */
    if (in->reset && !port->prev_reset) {
        (void)abbe_comp_reset(&port->comp);
        port->enabled = 0;
    }
    port->prev_reset = in->reset;
    int run = in->enable && in->homed && in->machine_on && port->n_tables > 0u;
    if (run && !port->enabled) {
        (void)abbe_comp_enable(&port->comp);
        port->enabled = 1;
    } else if (!run && port->enabled) {
        (void)abbe_comp_disable(&port->comp);
        port->enabled = 0;
    }

    /* Inputs. A NaN/Inf position (or temperature, where the table uses them;
     * or angle, or a kinstype naming no known kinematics, in five-axis mode)
     * is a bad input: the compensator holds, then fades out after stale_s. */
    const int five = port->kind != ABBE_KIN_NONE;
    int fresh = 1;
    int32_t pos_nm[ABBE_AXES];
    double angle_deg[ABBE_ROTARY_AXES] = {0.0, 0.0};
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        if (finite_d(in->pos_mm[j])) {
            pos_nm[j] = mm_to_nm(in->pos_mm[j]);
        } else {
            pos_nm[j] = 0;
            fresh = 0;
        }
    }
    int32_t frame = abbe_lcnc_frame_of(port, in->kinstype);
    if (five) {
        for (unsigned r = 0; r < ABBE_ROTARY_AXES; r++) {
            if (finite_d(in->angle_deg[r])) {
                angle_deg[r] = in->angle_deg[r];
            } else {
                fresh = 0;
            }
        }
        if (frame == ABBE_LCNC_FRAME_UNKNOWN) {
            port_flags |= ABBE_LCNC_FLAG_KINS;
            fresh = 0;
        }
    }
    int thermal = port->n_tables > 0u &&
                  (abbe_model_features(&port->model[port->active].linear) & ABBE_FEATURE_THERMAL) != 0u;
    for (unsigned j = 0; thermal && j < ABBE_AXES; j++) {
        if (!finite_d(in->temp_c[j])) {
            fresh = 0;
        }
    }
    if (fresh) {
        /* The direction from the commanded motion itself; the positions the
         * model sees, ahead. (A direction from the extrapolated positions
         * would take the overshoot of every stop for a reversal.) */
        follow_direction(port, pos_nm, port->deadband_nm);
        lead(port, pos_nm, angle_deg);
        for (unsigned r = 0; r < ABBE_ROTARY_AXES; r++) {
            angle_deg[r] = abbe_lcnc_reduce_deg(angle_deg[r]);
        }
    } else {
        port->have_last = 0; /* the lead restarts from the next valid position */
    }

    /* The table's thermal block (format 1.3, 3-axis): sample the th-in pins
     * every thermal_sample_s into the runtime; every period adds its error. */
    abbe_thermal_state_t *th = NULL;
    if (!five && port->n_tables > 0u && port->thermal[port->active].n_channels != 0u) {
        double period_s = (double)period_ns * 1e-9;
        int64_t sample_ns = round_i64(params->thermal_sample_s * 1e9); /* counted in whole ns: no drift */
        if (port->th_table != port->active) {
            if (port->variant == ABBE_LCNC_VARIANT_F32) {
                (void)abbe_thermal_init_f32(&port->th, &port->thermal[port->active], (float)period_s);
            } else {
                (void)abbe_thermal_init_q(&port->th, &port->thermal[port->active],
                                          (uint32_t)(period_ns / 1000L > 0L ? period_ns / 1000L : 1L));
            }
            port->th_table = port->active;
            port->th_clock_ns = sample_ns; /* the first sample now */
        } else {
            port->th_clock_ns += period_ns;
        }
        if (port->th_clock_ns >= sample_ns) {
            uint32_t valid = 0;
            const abbe_thermal_model_t *tm = &port->thermal[port->active];
            double dt_s = (double)port->th_clock_ns * 1e-9;
            if (port->variant == ABBE_LCNC_VARIANT_F32) {
                float x[ABBE_LCNC_TH_INPUTS];
                for (unsigned k = 0; k < ABBE_LCNC_TH_INPUTS; k++) {
                    x[k] = (float)in->th_in[k]; /* NaN stays NaN: the runtime's RANGE fault */
                    valid |= in->th_fault[k] ? 0u : 1u << k;
                }
                (void)abbe_thermal_update_f32(&port->th, x, valid, (float)dt_s);
            } else {
                int32_t x[ABBE_LCNC_TH_INPUTS];
                for (unsigned k = 0; k < ABBE_LCNC_TH_INPUTS; k++) {
                    double v = in->th_in[k] * (tm->kind[k] == ABBE_THERMAL_SPEED ? 1.0 : 1000.0);
                    /* NaN/Inf and the absurd: a value no input accepts (RANGE) */
                    x[k] = finite_d(v) && v > -2e9 && v < 2e9 ? (int32_t)round_i64(v) : INT32_MAX;
                    valid |= in->th_fault[k] ? 0u : 1u << k;
                }
                double ms = dt_s * 1000.0;
                (void)abbe_thermal_update_q(&port->th, x, valid,
                                            (uint32_t)(ms < 1.0 ? 1.0 : (ms > 2e9 ? 2e9 : ms + 0.5)));
            }
            port->th_clock_ns = 0;
            port->th_samples++;
        }
        th = &port->th;
    } else {
        port->th_table = -1;
    }

    abbe_comp_output5_t co;
    uint8_t fault_mask = 0;
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        fault_mask = (uint8_t)(fault_mask | (in->axis_fault[j] ? 1u << j : 0u));
    }
    if (port->variant == ABBE_LCNC_VARIANT_F32) {
        abbe_comp_input5_f32_t ci;
        for (unsigned j = 0; j < ABBE_AXES; j++) {
            ci.lin.pos_mm[j] = fresh ? (float)((double)pos_nm[j] / NM_PER_MM) : (float)in->pos_mm[j];
            ci.lin.temp_c[j] = thermal ? (float)in->temp_c[j] : 0.0f;
            ci.lin.dir[j] = port->dir[j];
        }
        ci.lin.fresh = (uint8_t)fresh;
        ci.lin.axis_fault_mask = fault_mask;
        if (five) {
            ci.angle_deg[0] = (float)angle_deg[0];
            ci.angle_deg[1] = (float)angle_deg[1];
            (void)abbe_comp_step5_f32(&port->comp, &ci, &co);
        } else {
            (void)abbe_comp_step_thermal_f32(&port->comp, th, &ci.lin, &co.lin);
        }
    } else {
        abbe_comp_input5_q_t ci;
        for (unsigned j = 0; j < ABBE_AXES; j++) {
            ci.lin.pos_nm[j] = pos_nm[j];
            ci.lin.temp_mdegc[j] = (thermal && fresh) ? c_to_mdegc(in->temp_c[j]) : 0;
            ci.lin.dir[j] = port->dir[j];
        }
        ci.lin.fresh = (uint8_t)fresh;
        ci.lin.axis_fault_mask = fault_mask;
        if (five) {
            for (unsigned r = 0; r < ABBE_ROTARY_AXES; r++) { /* |angle| <= 180: in range */
                ci.angle_udeg[r] = (int32_t)round_i64(angle_deg[r] * 1e6);
            }
            (void)abbe_comp_step5_q(&port->comp, &ci, &co);
        } else {
            (void)abbe_comp_step_thermal_q(&port->comp, th, &ci.lin, &co.lin);
        }
    }
    if (!five) {
        co.orient_nrad[0] = co.orient_nrad[1] = co.orient_nrad[2] = 0;
    }

    /* The correction in the frame the offsets are added in (five-axis, trt
     * kinematics: workpiece coordinates at this period's lead angles; an
     * unknown frame keeps the last one: the correction is fading out anyway). */
    if (frame != ABBE_LCNC_FRAME_UNKNOWN) {
        port->frame = frame;
    }
    int64_t world_nm[ABBE_AXES];
    if (five && port->frame == ABBE_LCNC_FRAME_WORKPIECE) {
        double v[3], w[3];
        for (unsigned j = 0; j < ABBE_AXES; j++) {
            v[j] = (double)co.lin.corr_nm[j];
        }
        abbe_lcnc_joints_to_workpiece(port->kind, fresh ? angle_deg : port->held_angle_deg, v, w);
        for (unsigned j = 0; j < ABBE_AXES; j++) {
            world_nm[j] = round_i64(w[j]);
        }
    } else {
        for (unsigned j = 0; j < ABBE_AXES; j++) {
            world_nm[j] = co.lin.corr_nm[j];
        }
    }
    if (fresh) {
        port->held_angle_deg[0] = angle_deg[0];
        port->held_angle_deg[1] = angle_deg[1];
    }

    /* The counts: move LinuxCNC's register toward the correction, within the
     * rate limit, only while LinuxCNC takes changes (a change written while it
     * does not would be dropped by it and is therefore not written). */
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        int32_t delta = 0;
        if (accepting) {
            int64_t want = world_nm[j] - port->accepted_nm[j];
            int64_t rate = port->cfg.rate_nm_per_cycle[j];
            delta = (int32_t)(want > rate ? rate : (want < -rate ? -rate : want));
            if (want != delta) {
                port_flags |= ABBE_LCNC_FLAG_CATCHUP;
            }
        }
        port->counts[j] += (uint32_t)delta; /* wraps like LinuxCNC's s32 difference */
        port->pending_nm[j] = delta;
        out->counts[j] = u32_to_i32(port->counts[j]);
        out->corr_mm[j] = (double)co.lin.corr_nm[j] / NM_PER_MM;
        out->target_mm[j] = (double)co.lin.target_nm[j] / NM_PER_MM;
        out->offset_mm[j] = (double)port->accepted_nm[j] / NM_PER_MM;
        out->orient_urad[j] = (double)co.orient_nrad[j] / 1000.0;
    }
    out->frame = five ? frame : ABBE_LCNC_FRAME_JOINTS;
    abbe_comp_output_t *col = &co.lin;
    out->eoffset_scale = port->eoffset_scale;
    out->flags = col->flags | port_flags;
    out->state = (int32_t)col->state;
    int idx = running_index(port);
    out->table_active = idx;
    out->model_crc = idx >= 0 ? abbe_model_crc(&port->model[idx].linear) : 0u;
    out->warning = (col->flags & ABBE_FLAG_WARN) != 0u;
    out->fault = col->state == ABBE_COMP_FAULT;
    out->config_error = port->params_bad;
    out->stats = abbe_comp_stats(&port->comp);
    out->config_errors = port->config_errors;
    out->th_flags = th != NULL ? abbe_thermal_flags(th) : 0u;
    out->th_input_faults = th != NULL ? abbe_thermal_input_faults(th) : 0u;
    out->th_samples = port->th_samples;
    for (unsigned c = 0; c < ABBE_LCNC_TH_CHANNELS; c++) {
        out->th_channel[c] = 0.0;
    }
    if (th != NULL) {
        if (port->variant == ABBE_LCNC_VARIANT_F32) {
            float y[ABBE_THERMAL_MAX_CHANNELS];
            unsigned n = abbe_thermal_channels_f32(th, y);
            for (unsigned c = 0; c < n; c++) {
                out->th_channel[c] = (double)y[c];
            }
        } else {
            int32_t y[ABBE_THERMAL_MAX_CHANNELS];
            unsigned n = abbe_thermal_channels_q(th, y);
            for (unsigned c = 0; c < n; c++) {
                out->th_channel[c] = (double)y[c] / 1000.0;
            }
        }
    }
}
