component abbe "Volumetric (21-error) geometric error compensation through external axis offsets";

description """
Evaluates an abbe error table (the 21 geometric errors of a 3-axis machine:
positioning, straightness, roll/pitch/yaw per axis and the three squareness
errors, plus the Abbe terms of the table's tool offset, backlash and thermal
terms) at the commanded axis positions once per servo period, and turns it into
rate-limited, faded, limit-checked corrections for LinuxCNC's external axis
offsets (axis.L.eoffset-counts / axis.L.eoffset-scale).

Build and install: port/linuxcnc/build.sh --install (abbe repository).
Wiring, safety behaviour and the table workflow: docs/linuxcnc.md.

\\fBloadrt abbe table=\\fIFILE\\fR[,\\fIFILE\\fR...] [\\fBvariant=q\\fR|\\fBf32\\fR]

\\fBtable\\fR: up to 4 table files (model.bin, written by abbe fit / abbe table);
each is validated completely at load time and a bad one refuses the load with
the library's reason. The first runs; \\fBtable-select\\fR switches at a cycle
boundary. A relative path is relative to the directory LinuxCNC was started in
(the configuration's directory).
\\fBvariant\\fR: q (default; integer evaluation from positions in nm) or f32.

Five-axis mode (tables of format 1.2 with a rotary section, written by abbe
fit on a five-axis machine file or by abbe export -f linuxcnc-trt as
abbe-five.bin; all tables of one kinematics): the inputs are the JOINT
positions (x/y/z.pos-mm from joint.0..2.pos-cmd, tilt.pos-deg and c.pos-deg
from joint.3/4.pos-cmd); the tool tip error is corrected through X, Y, Z and
the orientation error the linear axes cannot correct is reported on
orient-x/y/z-urad. External offsets are added in LinuxCNC's world
coordinates: under identity kinematics those are the joints and the offsets
are the correction itself; under the trt kinematics (tool-centre-point) they
are workpiece coordinates and the offsets are the correction turned back
through the table's rotation (frame 1). \\fBkinstype\\fR (net it to the signal
that drives motion.switchkins-type) says which is in force, by the values of
kins-identity and kins-tcp.
A module built with a compiled-in table (build.sh --builtin) uses it when no
\\fBtable\\fR is given.
""";

// ---- inputs, per axis (x, y, z) ------------------------------------------
pin in float x.pos_mm "Commanded X position, machine coordinates, mm: axis.x.pos-cmd (excludes the external offset); five-axis: joint.0.pos-cmd";
pin in float y.pos_mm "Commanded Y position, mm: axis.y.pos-cmd; five-axis: joint.1.pos-cmd";
pin in float z.pos_mm "Commanded Z position, mm: axis.z.pos-cmd; five-axis: joint.2.pos-cmd";
pin in float tilt.pos_deg "Five-axis: tilt joint position (A; B for xyzbc-trt), degrees: joint.3.pos-cmd; format 1.4 kinds: the first rotary joint alphabetically (B for 5axiskins / maxkins, A for xyzab-tdr)";
pin in float c.pos_deg "Five-axis: C joint position, degrees: joint.4.pos-cmd; format 1.4 kinds: the second rotary joint alphabetically (C; B for xyzab-tdr)";
pin in float kinstype "Five-axis: the kinematics in force (the signal driving motion.switchkins-type)";
pin in float x.temp_c = 20.0 "X axis temperature, deg C (used when the table has thermal terms)";
pin in float y.temp_c = 20.0 "Y axis temperature, deg C";
pin in float z.temp_c = 20.0 "Z axis temperature, deg C";
pin in bit x.axis_fault "TRUE: the X correction fades out";
pin in bit y.axis_fault "TRUE: the Y correction fades out";
pin in bit z.axis_fault "TRUE: the Z correction fades out";

// ---- thermal block (tables of format 1.3; docs/linuxcnc.md, "Thermal block") ----
pin in float th.in_##[17] "Thermal input NN of the table's thermal block: a temperature in deg C, or the spindle speed input in rpm (the table says which); sampled every thermal-sample-s";
pin in bit th.fault_##[17] "TRUE: no reading of thermal input NN (open circuit): the channels that read it hold and fade out";
pin out u32 th.flags "The thermal runtime's flags (ABBE_THERMAL_F_*: 1 open, 2 range, 4 step, 8 missing sample, 16 limit, 32 hold, 64 fading, 128 stuck); 0 without a thermal block";
pin out u32 th.input_faults "Bit k: thermal input k faulted at the last sample";
pin out float th.channel_##[5] "Thermal channel NN (the table's order), um (urad for tilts), before its fade";
pin out u32 th.samples "Thermal samples taken";

// ---- inputs, machine state --------------------------------------------------
pin in bit enable "Compensation wanted (fades in / out over fade-s)";
pin in bit homed "Every joint homed: motion.is-all-homed";
pin in bit machine_on "Motion enabled: motion.motion-enabled";
pin in bit reset "Rising edge: clear a latched limit fault";
pin in s32 table_select "Index of the table to run (0 = first table= file)";

// ---- outputs, per axis ------------------------------------------------------
pin out float x.corr_mm "X correction (faded, rate limited), mm";
pin out float y.corr_mm "Y correction, mm";
pin out float z.corr_mm "Z correction, mm";
pin out float x.target_mm "X correction the model asks for (unfaded), mm";
pin out float y.target_mm "Y correction the model asks for, mm";
pin out float z.target_mm "Z correction the model asks for, mm";
pin out float x.offset_mm "X external offset LinuxCNC has been asked for (as axis.x.eoffset-request), mm; five-axis: in the world frame (see frame), corr-mm and target-mm in the joint frame";
pin out float y.offset_mm "Y external offset LinuxCNC has been asked for, mm";
pin out float z.offset_mm "Z external offset LinuxCNC has been asked for, mm";
pin out s32 x.counts "To axis.x.eoffset-counts (1 count = 1 nm)";
pin out s32 y.counts "To axis.y.eoffset-counts";
pin out s32 z.counts "To axis.z.eoffset-counts";
pin out float orient_x_urad "Five-axis: tool orientation error about X the linear axes cannot correct (rotation vector, machine frame), urad";
pin out float orient_y_urad "Five-axis: orientation error about Y, urad";
pin out float orient_z_urad "Five-axis: orientation error about Z, urad";

// ---- outputs, state -----------------------------------------------------------
pin out float eoffset_scale "To axis.L.eoffset-scale: 1 nm in machine units";
pin out s32 kind "Kinematics of the tables: 0 3-axis, 1 xyzac-trt, 2 xyzbc-trt, 3 xyzbc-hh (5axiskins), 4 xyzbc-ht (maxkins), 5 xyzab-tdr";
pin out s32 frame "Frame of the offsets: 0 joints (3-axis, identity kinematics), 1 workpiece (trt kinematics), -1 unknown kinstype (fading out)";
pin out s32 state "0 off (or fading out), 1 on, 2 fault (latched until reset)";
pin out bit active "State on and not held: corrections are being applied";
pin out bit warning "A correction target is above its warning limit";
pin out bit fault "An error limit tripped (latched until reset)";
pin out bit config_error "A parameter is out of range: the last valid configuration stays";
pin out u32 flags "ABBE_FLAG_* | port flags (docs/linuxcnc.md)";
pin out u32 model_crc "CRC-32 of the running table";
pin out s32 table_active "Index of the running table";
pin out s32 tables "Number of tables loaded";
pin out u32 cycles "Servo periods run";
pin out u32 faults "Error-limit trips";
pin out u32 invalid_inputs "Periods with a NaN/Inf position or temperature";
pin out u32 rate_limited "Periods with a rate-limited correction";
pin out u32 model_swaps "Tables taken into use";
pin out u32 config_errors "Rejected parameter changes";

// ---- parameters (change at run time without a jump) ---------------------------
param rw float x.warn_mm "X warning limit on |correction|, mm (> 0)";
param rw float y.warn_mm "Y warning limit, mm";
param rw float z.warn_mm "Z warning limit, mm";
param rw float x.limit_mm "X error limit, mm (>= warn): fault, fade out";
param rw float y.limit_mm "Y error limit, mm";
param rw float z.limit_mm "Z error limit, mm";
param rw float x.rate_mm_per_s "X max correction speed, mm/s (> 0)";
param rw float y.rate_mm_per_s "Y max correction speed, mm/s";
param rw float z.rate_mm_per_s "Z max correction speed, mm/s";
param rw s32 x.sign "+1 or -1: X correction = sign * -dX";
param rw s32 y.sign "+1 or -1: Y correction = sign * -dY";
param rw s32 z.sign "+1 or -1: Z correction = sign * -dZ";
param rw float fade_s "Duration of a full fade in or out, s";
param rw float stale_s "Invalid input for this long: fade out, s";
param rw float dir_deadband_mm "Reverse motion that turns the backlash direction, mm";
param rw float lead_periods "Evaluate the model this many servo periods ahead (LinuxCNC applies an offset 2 periods late)";
param rw float machine_unit_mm "mm per machine length unit: 1 (mm) or 25.4 (inch); sets eoffset-scale";
param rw s32 kins_identity "Five-axis: kinstype of identity kinematics (0 with sparm=identityfirst, as the trt sample configs)";
param rw float thermal_sample_s "Thermal block: sample the th.in pins this often, s (0.001 .. 3600)";
param rw s32 kins_tcp "Five-axis: kinstype of the trt (tool-centre-point) kinematics (1 with sparm=identityfirst; != kins-identity)";

option singleton yes;
option extra_setup yes;

function _ fp "One compensator cycle: add to the servo thread after motion-controller";

license "Apache-2.0";
author "abbe contributors";
;;

/* halcompile defines a macro per pin and parameter (x_pos_mm for
 * abbe.x.pos-mm ...); the same words are field names of the port's and the
 * library's structs (enable, state, flags, cycles ...), so this file turns
 * them off and reads the instance through PIN() and PARAM(). */
#undef x_pos_mm
#undef y_pos_mm
#undef z_pos_mm
#undef tilt_pos_deg
#undef c_pos_deg
#undef kinstype
#undef orient_x_urad
#undef orient_y_urad
#undef orient_z_urad
#undef kind
#undef frame
#undef kins_identity
#undef kins_tcp
#undef th_in
#undef th_fault
#undef th_flags
#undef th_input_faults
#undef th_channel
#undef th_samples
#undef thermal_sample_s
#undef x_temp_c
#undef y_temp_c
#undef z_temp_c
#undef x_axis_fault
#undef y_axis_fault
#undef z_axis_fault
#undef enable
#undef homed
#undef machine_on
#undef reset
#undef table_select
#undef x_corr_mm
#undef y_corr_mm
#undef z_corr_mm
#undef x_target_mm
#undef y_target_mm
#undef z_target_mm
#undef x_offset_mm
#undef y_offset_mm
#undef z_offset_mm
#undef x_counts
#undef y_counts
#undef z_counts
#undef eoffset_scale
#undef state
#undef active
#undef warning
#undef fault
#undef config_error
#undef flags
#undef model_crc
#undef table_active
#undef tables
#undef cycles
#undef faults
#undef invalid_inputs
#undef rate_limited
#undef model_swaps
#undef config_errors
#undef x_warn_mm
#undef y_warn_mm
#undef z_warn_mm
#undef x_limit_mm
#undef y_limit_mm
#undef z_limit_mm
#undef x_rate_mm_per_s
#undef y_rate_mm_per_s
#undef z_rate_mm_per_s
#undef x_sign
#undef y_sign
#undef z_sign
#undef fade_s
#undef stale_s
#undef dir_deadband_mm
#undef lead_periods
#undef machine_unit_mm
#define PIN(name) (*__comp_inst->name)
#define PARAM(name) (__comp_inst->name)

#include "abbe_lcnc.h"
#include "abbe_lcnc_file.h"
#ifdef ABBE_LCNC_BUILTIN_TABLE
#include "abbe_model.h" /* build.sh --builtin DIR: abbe table cgen output */
#endif

/* Module parameters. */
static char *table[ABBE_LCNC_MAX_TABLES];
RTAPI_MP_ARRAY_STRING(table, ABBE_LCNC_MAX_TABLES, "table files (model.bin), the first runs");
static char *variant = "q";
RTAPI_MP_STRING(variant, "evaluation variant: q (default) or f32");

/* All memory is static: the port state and the tables, which are read once at
 * load time and never written again (the realtime function only reads them). */
static abbe_lcnc_t abbe_port;
static uint32_t abbe_table_store[ABBE_LCNC_MAX_TABLES][ABBE_LCNC_TABLE_MAX_BYTES / 4u];

static void read_params(struct __comp_state *__comp_inst, abbe_lcnc_params_t *p)
{
    p->warn_mm[0] = PARAM(x_warn_mm);
    p->warn_mm[1] = PARAM(y_warn_mm);
    p->warn_mm[2] = PARAM(z_warn_mm);
    p->limit_mm[0] = PARAM(x_limit_mm);
    p->limit_mm[1] = PARAM(y_limit_mm);
    p->limit_mm[2] = PARAM(z_limit_mm);
    p->rate_mm_per_s[0] = PARAM(x_rate_mm_per_s);
    p->rate_mm_per_s[1] = PARAM(y_rate_mm_per_s);
    p->rate_mm_per_s[2] = PARAM(z_rate_mm_per_s);
    p->sign[0] = PARAM(x_sign);
    p->sign[1] = PARAM(y_sign);
    p->sign[2] = PARAM(z_sign);
    p->fade_s = PARAM(fade_s);
    p->stale_s = PARAM(stale_s);
    p->dir_deadband_mm = PARAM(dir_deadband_mm);
    p->lead_periods = PARAM(lead_periods);
    p->machine_unit_mm = PARAM(machine_unit_mm);
    p->kins_identity = PARAM(kins_identity);
    p->kins_tcp = PARAM(kins_tcp);
    p->thermal_sample_s = PARAM(thermal_sample_s);
}

FUNCTION(_) {
    abbe_lcnc_params_t p;
    abbe_lcnc_input_t in;
    abbe_lcnc_output_t out;

    memset(&p, 0, sizeof p); /* padding too: the port compares parameter sets bytewise */
    read_params(__comp_inst, &p);
    in.pos_mm[0] = PIN(x_pos_mm);
    in.pos_mm[1] = PIN(y_pos_mm);
    in.pos_mm[2] = PIN(z_pos_mm);
    in.angle_deg[0] = PIN(tilt_pos_deg);
    in.angle_deg[1] = PIN(c_pos_deg);
    in.kinstype = PIN(kinstype);
    in.temp_c[0] = PIN(x_temp_c);
    in.temp_c[1] = PIN(y_temp_c);
    in.temp_c[2] = PIN(z_temp_c);
    in.axis_fault[0] = PIN(x_axis_fault);
    in.axis_fault[1] = PIN(y_axis_fault);
    in.axis_fault[2] = PIN(z_axis_fault);
    in.enable = PIN(enable);
    in.homed = PIN(homed);
    in.machine_on = PIN(machine_on);
    in.reset = PIN(reset);
    in.table_select = PIN(table_select);
    for (unsigned k = 0; k < ABBE_LCNC_TH_INPUTS; k++) {
        in.th_in[k] = *__comp_inst->th_in[k];
        in.th_fault[k] = *__comp_inst->th_fault[k] ? 1u : 0u;
    }

    abbe_lcnc_step(&abbe_port, &p, period, &in, &out);

    PIN(x_corr_mm) = out.corr_mm[0];
    PIN(y_corr_mm) = out.corr_mm[1];
    PIN(z_corr_mm) = out.corr_mm[2];
    PIN(x_target_mm) = out.target_mm[0];
    PIN(y_target_mm) = out.target_mm[1];
    PIN(z_target_mm) = out.target_mm[2];
    PIN(x_offset_mm) = out.offset_mm[0];
    PIN(y_offset_mm) = out.offset_mm[1];
    PIN(z_offset_mm) = out.offset_mm[2];
    PIN(x_counts) = out.counts[0];
    PIN(y_counts) = out.counts[1];
    PIN(z_counts) = out.counts[2];
    PIN(orient_x_urad) = out.orient_urad[0];
    PIN(orient_y_urad) = out.orient_urad[1];
    PIN(orient_z_urad) = out.orient_urad[2];
    PIN(th_flags) = out.th_flags;
    PIN(th_input_faults) = out.th_input_faults;
    PIN(th_samples) = out.th_samples;
    for (unsigned c = 0; c < ABBE_LCNC_TH_CHANNELS; c++) {
        *__comp_inst->th_channel[c] = out.th_channel[c];
    }
    PIN(kind) = (rtapi_s32)abbe_lcnc_kind(&abbe_port);
    PIN(frame) = out.frame;
    PIN(eoffset_scale) = out.eoffset_scale;
    PIN(state) = out.state;
    PIN(active) = out.state == ABBE_COMP_ON && (out.flags & ABBE_LCNC_FLAG_HOLD) == 0u;
    PIN(warning) = out.warning;
    PIN(fault) = out.fault;
    PIN(config_error) = out.config_error;
    PIN(flags) = out.flags;
    PIN(model_crc) = out.model_crc;
    PIN(table_active) = out.table_active;
    PIN(cycles) = out.stats.cycles;
    PIN(faults) = out.stats.limit_trips;
    PIN(invalid_inputs) = out.stats.invalid_inputs;
    PIN(rate_limited) = out.stats.rate_limited;
    PIN(model_swaps) = out.stats.model_swaps;
    PIN(config_errors) = out.config_errors;
    PIN(tables) = (rtapi_s32)abbe_lcnc_table_count(&abbe_port);
}

EXTRA_SETUP() {
    abbe_lcnc_params_t p;
    abbe_lcnc_variant_t v;
    unsigned i;
    (void)prefix;
    (void)extra_arg;

    if (strcmp(variant, "q") == 0) {
        v = ABBE_LCNC_VARIANT_Q;
    } else if (strcmp(variant, "f32") == 0) {
        v = ABBE_LCNC_VARIANT_F32;
    } else {
        rtapi_print_msg(RTAPI_MSG_ERR, "abbe: variant=%s: expected q or f32\n", variant);
        return -EINVAL;
    }
    abbe_lcnc_default_params(&p);
    if (abbe_lcnc_init(&abbe_port, v, &p, 1000000L) != ABBE_OK) {
        rtapi_print_msg(RTAPI_MSG_ERR, "abbe: internal error: default parameters rejected\n");
        return -EINVAL;
    }
    if (table[0] == NULL || table[0][0] == '\0') {
#ifdef ABBE_LCNC_BUILTIN_TABLE
        abbe_status_t st = abbe_lcnc_add_table(&abbe_port, abbe_model_blob, abbe_model_blob_size);
        if (st != ABBE_OK) {
            rtapi_print_msg(RTAPI_MSG_ERR, "abbe: built-in table refused: %s (status %d)\n",
                            abbe_strerror(st), (int)st);
            return -EINVAL;
        }
        rtapi_print_msg(RTAPI_MSG_INFO, "abbe: built-in table, CRC-32 0x%08X\n",
                        (unsigned)abbe_lcnc_table_crc(&abbe_port, 0));
#else
        rtapi_print_msg(RTAPI_MSG_ERR, "abbe: table=FILE is required (an abbe table, model.bin)\n");
        return -EINVAL;
#endif
    }
    for (i = 0; i < ABBE_LCNC_MAX_TABLES && table[i] != NULL && table[i][0] != '\0'; i++) {
        char why[160];
        size_t size = 0;
        abbe_status_t st;
        if (abbe_lcnc_read_file(table[i], abbe_table_store[i], sizeof abbe_table_store[i], &size,
                                why, sizeof why) != 0) {
            rtapi_print_msg(RTAPI_MSG_ERR, "abbe: table %s: %s\n", table[i], why);
            return -EINVAL;
        }
        if (i > 0 && abbe_lcnc_blob_kind(abbe_table_store[i], size) != abbe_lcnc_kind(&abbe_port)) {
            rtapi_print_msg(RTAPI_MSG_ERR,
                            "abbe: table %s: kinematics %u (0 3-axis, 1 xyzac-trt, 2 xyzbc-trt) differs "
                            "from the first table's %u: one kind for all tables\n",
                            table[i], (unsigned)abbe_lcnc_blob_kind(abbe_table_store[i], size),
                            (unsigned)abbe_lcnc_kind(&abbe_port));
            return -EINVAL;
        }
        st = abbe_lcnc_add_table(&abbe_port, abbe_table_store[i], size);
        if (st != ABBE_OK) {
            rtapi_print_msg(RTAPI_MSG_ERR, "abbe: table %s refused: %s (status %d)\n", table[i],
                            abbe_strerror(st), (int)st);
            return -EINVAL;
        }
        rtapi_print_msg(RTAPI_MSG_INFO, "abbe: table %u: %s, %zu bytes, CRC-32 0x%08X\n", i, table[i],
                        size, (unsigned)abbe_lcnc_table_crc(&abbe_port, i));
    }

    /* Parameters (struct members, unlike the pins, already exist) start at
     * the port's defaults (one source: abbe_lcnc_default_params). */
    PARAM(x_warn_mm) = p.warn_mm[0];
    PARAM(y_warn_mm) = p.warn_mm[1];
    PARAM(z_warn_mm) = p.warn_mm[2];
    PARAM(x_limit_mm) = p.limit_mm[0];
    PARAM(y_limit_mm) = p.limit_mm[1];
    PARAM(z_limit_mm) = p.limit_mm[2];
    PARAM(x_rate_mm_per_s) = p.rate_mm_per_s[0];
    PARAM(y_rate_mm_per_s) = p.rate_mm_per_s[1];
    PARAM(z_rate_mm_per_s) = p.rate_mm_per_s[2];
    PARAM(x_sign) = p.sign[0];
    PARAM(y_sign) = p.sign[1];
    PARAM(z_sign) = p.sign[2];
    PARAM(fade_s) = p.fade_s;
    PARAM(stale_s) = p.stale_s;
    PARAM(dir_deadband_mm) = p.dir_deadband_mm;
    PARAM(lead_periods) = p.lead_periods;
    PARAM(machine_unit_mm) = p.machine_unit_mm;
    PARAM(kins_identity) = p.kins_identity;
    PARAM(kins_tcp) = p.kins_tcp;
    PARAM(thermal_sample_s) = p.thermal_sample_s;
    return 0; /* pins do not exist yet here: FUNCTION writes every output */
}
