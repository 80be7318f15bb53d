/* Eva harness: the five-axis evaluations on a model of ANY layout the
 * five-axis loader accepts (eval_five_any_q with PROOF_Q: abbe_five_error_eval_q
 * and the compensator's five-axis cycle abbe_comp_step5_q; eval_five_any_f32
 * (PROOF_NO_COMP): abbe_five_error_eval_f32 and the contracts of its two parts,
 * five_eval_f32_contract.h; comp_five_any_f32 (PROOF_COMP_ONLY): the cycles of
 * abbe_comp_step5_f32 with those parts as their contracts: with them as they
 * are, the cycles took over 63 s of CPU, unfinished).
 * The model is built
 * directly, every field unknown within the invariants abbe_five_model_load's
 * checks establish (model_load.c, model_load_rotary.h: check_rotary,
 * build_rotary), stated here as the evaluation's preconditions (the rotary
 * records' counts and ranges are also asserted as rotary_ranges_ok, their
 * location errors as rotary_location_ok, the predicates build_rotary's
 * WP-proven contract gives: model_load_rotary_acsl.h):
 *
 *   kind: 0 (a 3-axis table), the trunnions 1, 2 and the chain kinds 3-5
 *   (format 1.4), each its own partition; per kind the records' machine axes
 *   (dir), and for kinds 3-5 the angle slots, as the loader sets them, each
 *   record's sign +1 or -1;
 *   rot_point, offset, square_ref: each component within +/-GEOMETRY_CAP
 *   (2^30 - 1 nm); a trunnion's offset 0 along its tilt axis; tilt_pivot =
 *   rot_point + offset; the five-axis squareness within +/-2^28 (2^-36 rad);
 *   kind 3's HH_LEVER_L1_CAP is NOT imposed (a superset: an interval
 *   analysis cannot state a sum of magnitudes; five_eval_q.c's hh_lever);
 *   each rotary record: any component mask 0..63, n_comp its popcount,
 *   column[c] its rank or 0xFF; harmonics 0..8 (0 without components);
 *   location errors: delta any int32 (the loader has no cap on them), the
 *   two tilts and the zero offset within +/-2^26 (LOCATION_BOX: a box inside
 *   the loader's SQUARENESS_CAP, 2^28; docs/proofs.md says why), 0 along
 *   the axis; coef_q / coef_f32 an array of 2 x 8 x 6 = 96 words (the
 *   largest array: a read past it is an alarm; also where the loader leaves
 *   NULL, below);
 *   every word any int32 in [-2^24, 2^24] (+/-65.5 um in a linear
 *   component, 2^-8 nm; +/-244 urad in an angular one, 2^-36 rad: for 16
 *   rows the angular L1 cap, 2^28, and 1/16 of the linear one, 2^32),
 *   the float twins any float in the same range (a box inside the L1 caps);
 *   the linear axes: any layout as eval_q_any_layout.c (any_layout.h); in the
 *   _q harness the term kernel runs as its contract (terms_q_contract.h,
 *   proven by terms_q_any), in the _f32 one the kernels as they are.
 *
 * Then every int32 (_q) / finite (_f32) joint position, angle and direction
 * state, every temperature (_f32: within +/-10^6 degC), and the compensator
 * with any configuration and any number of cycles of any input, with resets
 * (docs/proofs.md, "Five-axis: any layout"). With PROOF_ROT_CAPS the
 * coefficients and location errors of the loader's caps instead (below, ROT_LO):
 * eval_five_any_q_caps with motions_q as its contract; eval_five_any_f32_caps
 * with the float kernels as they are, every float twin (rotary and linear axes)
 * any float within 2^31, the twin of any int32 (docs/proofs.md, "Five-axis: the
 * loader's caps, single precision"); comp_five_any_f32 on the same models (its
 * evaluation's parts as their contracts, which eval_five_any_f32_caps proves).
 * With PROOF_NONFINITE too (eval_five_any_f32_nonfinite) every position, angle,
 * direction state and temperature any 32 bits, NaN and the infinities included
 * (-warn-special-float none; the contracts, which require finite inputs, left out). */
#if defined(PROOF_Q)
#include "terms_q_contract.h"
#elif !defined(PROOF_NONFINITE) /* (the contracts require finite inputs) */
#include "five_eval_f32_contract.h" /* proven by eval_five_any_f32(_caps), used by comp_five_any_f32 */
#endif
#define PROOF_LAYOUT_COEF_UNION
#include "any_layout.h"

#include "abbe/comp.h"
#include "abbe/error.h"
#include "abbe/five_axis.h"

#include "comp5_cycles.h" /* any_i32, any_f32, the compensator's config and cycles */
#include "model_load_rotary_acsl.h" /* rotary_ranges_ok: the loader's statement (WP-proven, build_rotary) */

#define ROT_COEF_WORDS (2u * ABBE_ROTARY_MAX_HARMONICS * ABBE_MOTIONS)
#define GEOMETRY_BOX ((1 << 30) - 1)
#define ANGLE_BOX (1 << 28)
#if defined(PROOF_ROT_CAPS)
/* eval_five_any_q_caps (docs/proofs.md, "Five-axis: the loader's caps"): every
 * coefficient any int32, a superset of the loader's L1 caps (motions_q runs as its
 * contract, WP-proven for those caps: -eva-use-spec motions_q); the tilts and zero
 * offsets within the loader's SQUARENESS_CAP (2^28; the trunnion table axis' turned
 * angle sum bounded by a WP-proven assertion, tests/proofs/turn_q.c) */
#define ROT_LO INT32_MIN
#define ROT_HI INT32_MAX
/* _f32: a float twin is its int32 converted (check_twins, rotary_record_bad's
 * RC_MISMATCH), so within 2^31: any float in [-2^31, 2^31], a superset of every
 * accepted twin and of the L1 caps; the linear axes' twins too */
#define ROT_F_BOX 2147483648.0f
#define LIN_F_BOX 2147483648.0f
#define LOCATION_BOX (1 << 28)
#else
#define ROT_LO (-(1 << 24))
#define ROT_HI (1 << 24)
#define ROT_F_BOX 16777216.0f
#define LIN_F_BOX 134217728.0f /* 2^27: the union of any_layout.h's boxes */
#define LOCATION_BOX (1 << 26)
#endif

static abbe_five_model_t model;
static abbe_comp_t comp;
static int32_t coef[ABBE_AXES][ANY_COEF_WORDS];
static int32_t rot_coef[ABBE_ROTARY_AXES][ROT_COEF_WORDS];
#if !defined(PROOF_Q)
static float coef_f[ABBE_AXES][ANY_COEF_WORDS];
static float rot_coef_f[ABBE_ROTARY_AXES][ROT_COEF_WORDS];
#endif

/* the linear model's own fields as eval_q_any_layout.c / eval_f32_any_layout.c */
static void any_linear(abbe_model_t *m)
{
    memset(m, 0, sizeof *m);
    m->features = Frama_C_unsigned_int_interval(0u, ABBE_FEATURE_ALL);
    m->version_major = 1u;
    m->version_minor = (uint16_t)Frama_C_unsigned_int_interval(0u, 4u);
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        m->reference_nm[j] = any_i32();
        m->tool_offset_nm[j] = any_i32();
        m->squareness_q36[j] = Frama_C_int_interval(-ANGLE_BOX, ANGLE_BOX);
        m->ref_half_nm[j] = m->reference_nm[j] >> 1;
        any_axis(&m->axis[j], coef[j]);
#if !defined(PROOF_Q)
        m->tool_half_nm[j] = (float)m->tool_offset_nm[j] * 0.5f;
        m->squareness_f[j] = (float)m->squareness_q36[j];
        /*@ loop unroll 0; */
        for (unsigned i = 0; i < ANY_COEF_WORDS; i++) {
            coef_f[j][i] = Frama_C_float_interval(-LIN_F_BOX, LIN_F_BOX);
        }
        m->axis[j].coef_f32 = (const uint8_t *)coef_f[j];
#endif
    }
    for (unsigned k = 0; k < 2u; k++) {
        m->square_const_q36[k] = Frama_C_long_long_interval(-(1LL << 60), 1LL << 60);
    }
    m->five_view = 1u;
}

/* one rotary record turning about dir, as build_rotary leaves it */
static void any_rotary(abbe_rotary_model_t *ax, unsigned r, unsigned dir)
{
    /*@ split dir; */
    memset(ax, 0, sizeof *ax);
    const unsigned i1 = dir == 0u ? 1u : 0u, i2 = dir == 2u ? 1u : 2u;
    ax->dir = (uint8_t)dir;
    ax->delta_q8[i1] = any_i32();
    ax->delta_q8[i2] = any_i32();
    ax->phi_q36[i1] = Frama_C_int_interval(-LOCATION_BOX, LOCATION_BOX);
    ax->phi_q36[i2] = Frama_C_int_interval(-LOCATION_BOX, LOCATION_BOX);
    ax->zero_q36 = Frama_C_int_interval(-LOCATION_BOX, LOCATION_BOX);
    const unsigned mask = Frama_C_unsigned_int_interval(0u, 63u);
    unsigned n = 0;
    for (unsigned c = 0; c < ABBE_MOTIONS; c++) {
        if ((mask >> c) & 1u) {
            ax->column[c] = (uint8_t)n;
            n++;
        } else {
            ax->column[c] = 0xFFu;
        }
    }
    ax->comp_mask = (uint8_t)mask;
    ax->n_comp = (uint8_t)n;
    ax->harmonics = (uint8_t)(n != 0u ? Frama_C_unsigned_int_interval(0u, ABBE_ROTARY_MAX_HARMONICS) : 0u);
    /*@ loop unroll 0; */
    for (unsigned i = 0; i < ROT_COEF_WORDS; i++) {
        rot_coef[r][i] = Frama_C_int_interval(ROT_LO, ROT_HI);
#if !defined(PROOF_Q)
        rot_coef_f[r][i] = Frama_C_float_interval(-ROT_F_BOX, ROT_F_BOX);
#endif
    }
    /* always the record's buffer: where the loader leaves NULL (no components or no
     * harmonics) the evaluation reads nothing (rows 0; the golden harness
     * eval_five_*_ac_location runs that case with NULL), and Eva does not relate the
     * pointer to the row count when both are joined over the layouts */
    ax->coef_q = (const uint8_t *)rot_coef[r];
#if !defined(PROOF_Q)
    ax->coef_f32 = (const uint8_t *)rot_coef_f[r];
#endif
    /* the record's counts and ranges, and its location errors, are the predicates
     * build_rotary's proven contract gives (lib/src/model_load_rotary_acsl.h,
     * layout_ok; docs/proofs.md); the location's zeros along dir are a relation with
     * dir, which Eva checks per value of dir (split at the start, merged here: the
     * callers' states as before) */
    /*@ assert loader_ranges: rotary_ranges_ok(ax); */
    /*@ assert loader_location: rotary_location_ok(ax, dir); */
    /*@ merge dir; */
}

static void any_five(abbe_five_model_t *m5)
{
    memset(m5, 0, sizeof *m5);
    any_linear(&m5->linear);
    const unsigned kind = Frama_C_unsigned_int_interval(ABBE_KIN_NONE, ABBE_KIN_XYZAB_TDR);
    /*@ split kind; */
    if (kind == ABBE_KIN_NONE) {
        return; /* a 3-axis table: the rest zero (model_load.c) */
    }
    m5->kind = kind;
    for (unsigned k = 0; k < 3u; k++) {
        m5->rot_point_nm[k] = Frama_C_int_interval(-GEOMETRY_BOX, GEOMETRY_BOX);
        /* a trunnion's offset has no component along its tilt axis (check_rotary) */
        m5->offset_nm[k] = kind <= ABBE_KIN_XYZBC_TRT && k == kind - 1u ? 0 : Frama_C_int_interval(-GEOMETRY_BOX, GEOMETRY_BOX);
        m5->tilt_pivot_nm[k] = m5->rot_point_nm[k] + m5->offset_nm[k];
        m5->squareness_q36[k] = Frama_C_int_interval(-ANGLE_BOX, ANGLE_BOX);
    }
    if (kind >= ABBE_KIN_XYZBC_HH) {
        /* records' machine axes and angle slots: 3 C, B; 4 B, C; 5 B, A */
        static const uint8_t dirs[3][2] = {{2u, 1u}, {1u, 2u}, {1u, 0u}};
        const unsigned i = kind - ABBE_KIN_XYZBC_HH;
        for (unsigned r = 0; r < ABBE_ROTARY_AXES; r++) {
            any_rotary(&m5->rotary[r], r, dirs[i][r]);
            m5->sign[r] = Frama_C_nondet(0, 1) ? (int8_t)-1 : (int8_t)1;
            m5->slot[r] = (uint8_t)(i == 1u ? r : 1u - r);
        }
        for (unsigned k = 0; k < 3u; k++) {
            m5->square_ref_nm[k] = Frama_C_int_interval(-GEOMETRY_BOX, GEOMETRY_BOX);
        }
        return;
    }
    any_rotary(&m5->rotary[0], 0u, kind == ABBE_KIN_XYZAC_TRT ? 0u : 1u);
    any_rotary(&m5->rotary[1], 1u, 2u);
}

int main(void)
{
    any_five(&model);
    abbe_comp_config_t cfg;
    any5_config(&cfg);
#if defined(PROOF_COMP_ONLY)
    /* comp_five_any_f32: the compensator's cycles only (the evaluation on its own
     * is eval_five_any_f32's) */
#elif defined(PROOF_Q)
    abbe_five_input_q_t in;
    abbe_five_error_q_t out;
    for (unsigned j = 0; j < 3u; j++) {
        in.pos_nm[j] = any_i32();
        in.dir_state_q30[j] = any_i32();
        in.temp_mdegc[j] = any_i32();
    }
    in.angle_udeg[0] = any_i32();
    in.angle_udeg[1] = any_i32();
    (void)abbe_five_error_eval_q(&model, &in, &out);
#else
    abbe_five_input_f32_t in;
    abbe_five_error_f32_t out;
    for (unsigned j = 0; j < 3u; j++) {
        in.pos_mm[j] = any_f32();
        in.dir_state[j] = any_f32();
        in.temp_c[j] = any_temp();
    }
    in.angle_deg[0] = any_f32();
    in.angle_deg[1] = any_f32();
    (void)abbe_five_error_eval_f32(&model, &in, &out);
#endif
#if !defined(PROOF_NO_COMP)
    /* the compensator's five-axis cycle: any configuration, any number of cycles */
    if (abbe_comp_init(&comp, &cfg, &model.linear) != ABBE_OK || abbe_comp_enable(&comp) != ABBE_OK) {
        return 1;
    }
    any5_cycles(&comp, NULL);
#endif
    return 0;
}
