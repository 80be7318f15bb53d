/* abbe: a validated, in-place view of a coefficient table.
 *
 * abbe_model_load() checks a blob completely (docs/table-format.md) and fills a
 * caller-owned abbe_model_t with pointers into the blob plus the constants an
 * evaluation needs, derived once (reciprocals and phase offsets for the
 * argument reduction, the constant parts of Eq. 3, float twins of the scalar
 * fields). The blob is never copied and must stay valid and unchanged while
 * the model is in use. Loading uses integer arithmetic only (the float twins
 * are built bit by bit), so it also serves targets without an FPU.
 */
#ifndef ABBE_MODEL_H
#define ABBE_MODEL_H

#include <stddef.h>
#include <stdint.h>

#include "abbe/status.h"

/* C linkage for C++ callers (firmware in C++ links the C library). */
#ifdef __cplusplus
extern "C" {
#endif

#define ABBE_AXES 3            /* X, Y, Z */
#define ABBE_TERMS 6           /* per axis: d_x, d_y, d_z (linear), eps_x, eps_y, eps_z (angular) */
#define ABBE_BLOCKS 2          /* Fourier blocks per axis: 0 long wave, 1 short period */
#define ABBE_MAX_DEGREE 7      /* Chebyshev trend degree cap */
#define ABBE_NO_TREND 255u     /* trend_degree value meaning "no trend block" */
#define ABBE_MAX_HARMONICS 8   /* per Fourier block */
#define ABBE_MAX_BASIS (ABBE_MAX_DEGREE + 1 + 2 * ABBE_BLOCKS * ABBE_MAX_HARMONICS)
#define ABBE_MAX_REVERSAL_ROWS 8 /* reversal block: Chebyshev T_0 .. T_7 (format 1.1) */

enum { ABBE_AXIS_X = 0, ABBE_AXIS_Y = 1, ABBE_AXIS_Z = 2 };
enum {
    ABBE_TERM_DX = 0, ABBE_TERM_DY = 1, ABBE_TERM_DZ = 2,
    ABBE_TERM_EX = 3, ABBE_TERM_EY = 4, ABBE_TERM_EZ = 5
};

/* Feature bits of the table header. */
#define ABBE_FEATURE_SQUARENESS 0x1u
#define ABBE_FEATURE_TOOL_OFFSET 0x2u
#define ABBE_FEATURE_BACKLASH 0x4u
#define ABBE_FEATURE_THERMAL 0x8u
#define ABBE_FEATURE_REVERSAL 0x10u /* format 1.1: position-dependent reversal blocks; needs BACKLASH */
#define ABBE_FEATURE_ALL 0x1Fu      /* every bit this library knows (a 1.0 table may use 0xF) */

/* Fixed-point scalings of the table's integer fields (docs/numerics.md). */
#define ABBE_LIN_FRAC_BITS 8   /* linear coefficients: 2^-8 nm */
#define ABBE_ANG_FRAC_BITS 36  /* angular coefficients and squareness: 2^-36 rad */

/* Fixed-point position: signed nanometres, +/-2.147 m. */
typedef int32_t abbe_nm_t;

/* x86-64: the model also holds the lanes the x86-64-v3 phases load (so a
 * model's size depends on the target, like its pointers'). */
#if defined(__x86_64__) || defined(_M_X64)
#define ABBE_MODEL_X86_64_LANES 1
#endif

/* Per-axis view and evaluation plan, built once by abbe_model_load(). All
 * fields are private: read them through the accessors. Everything the
 * evaluation needs per call is precomputed here (integer reciprocals, phase
 * offsets), so a call does one shared argument reduction per axis. */
typedef struct {
    const uint8_t *coef_q;      /* int32 LE, n_basis x n_terms, row-major */
    const uint8_t *coef_f32;    /* float32 LE, same shape */
    uint64_t freq[ABBE_BLOCKS]; /* round(2^64 / period), 0 for an unused block */
    uint64_t phase_min[ABBE_BLOCKS]; /* phase at travel_min, Q64 turn: (min - origin) * freq mod 2^64 */
    uint64_t takeup_rate_q46;   /* round(2^46 / takeup_nm): direction-state change per nm, Q30 << 16 */
    int32_t travel_min_nm;
    int32_t travel_max_nm;
    uint32_t span_nm;           /* travel_max - travel_min */
    uint32_t cheb_mul;          /* u_q30 = hi32((d << cheb_shift) * cheb_mul + 2^31) - 2^30, d = p - min */
    int32_t backlash_reversal_q8;
    int32_t backlash_takeup_nm;
    int32_t thermal_expansion_q50;
    int32_t thermal_offset_q16;
    int32_t thermal_tref_mdegc;
    uint8_t cheb_shift;
    uint8_t term_mask;
    uint8_t n_terms;
    uint8_t trend_rows;         /* trend_degree + 1, or 0 */
    uint8_t harmonics[ABBE_BLOCKS];
    uint8_t n_basis;
    uint8_t column[ABBE_TERMS]; /* column of term t, or 0xFF if absent */
    uint8_t reversal_rows;      /* rows of the reversal block (0 = none), after the n_basis x n_terms matrix */
} abbe_axis_model_t;

/* A loaded model. Allocate it yourself (static, stack or struct member);
 * all fields are private. */
typedef struct {
    const uint8_t *blob;
    uint32_t size;
    uint32_t crc;
    uint32_t features;
    uint16_t version_major;
    uint16_t version_minor;
    int32_t reference_nm[ABBE_AXES];
    int32_t tool_offset_nm[ABBE_AXES];
    int32_t squareness_q36[3];  /* S_xy, S_xz, S_yz */
    /* Precomputed for the evaluation (integer only, exact); four lanes where
     * a SIMD kernel loads them as one vector (the fourth lane is 0): */
    int64_t square_const_q36[2];      /* constant lever part of the squareness in dX, dY, nm x 2^-36 rad */
    int32_t ref_half_nm[4];           /* reference_nm >> 1 (float lever arms in half nm) */
    int32_t lane_min_nm[4];           /* axis travel_min, travel_max, span: copies by axis */
    int32_t lane_max_nm[4];
    uint32_t lane_span_nm[4];
    uint32_t lane_cheb_shift[4];      /* axis cheb_shift, cheb_mul: copies by axis */
    uint32_t lane_cheb_mul[4];
    float tool_half_nm[4];            /* tool_offset_nm / 2, float (exact power-of-two scaling) */
    float squareness_f[3];            /* squareness_q36 as float, 2^-36 rad */
    float square_dx_dy[4];            /* {S_xy, -S_yz, 0, 0}: times {y, z}: the squareness of dX, dY */
    float square_dx_f[4];             /* {-S_xz, 0, 0, 0}: times z */
#if defined(ABBE_MODEL_X86_64_LANES)
    uint64_t lane_freq[ABBE_BLOCKS][4];      /* axis freq[b], phase_min[b]: copies by axis (x86-64-v3 phases) */
    uint64_t lane_phase_min[ABBE_BLOCKS][4];
#endif
    uint8_t any_block1;               /* some axis uses Fourier block 1 */
    uint8_t simd;                     /* x86-64: 1 if this CPU runs the x86-64-v3 (AVX2, FMA) kernels */
    uint8_t five_view;                /* 1: the `linear` member of an abbe_five_model_t (abbe/five_axis.h) */
    abbe_axis_model_t axis[ABBE_AXES];
} abbe_model_t;

/* Validate blob[0 .. size) and make *model a view of it.
 * Requires: model and blob non-NULL (else ABBE_E_ARG); blob 4-byte aligned
 * (else ABBE_E_ALIGN; generated C and malloc'd buffers are). size may exceed the
 * table's total_size (a flash sector); the extra bytes are ignored.
 * Returns ABBE_OK, or the status of the first failed check in the order of
 * docs/table-format.md. On failure *model is left untouched, so a model that was
 * loaded before stays usable. */
abbe_status_t abbe_model_load(abbe_model_t *model, const void *blob, size_t size);

/* CRC-32 (zlib) of the loaded table: identifies the running model. */
uint32_t abbe_model_crc(const abbe_model_t *model);

/* Feature bits (ABBE_FEATURE_*) of the loaded table. */
uint32_t abbe_model_features(const abbe_model_t *model);

/* Size of the table in bytes (its total_size field). */
uint32_t abbe_model_size(const abbe_model_t *model);

/* What a port needs to know about one axis of the loaded table: its travel
 * (the model holds its end values beyond it), the backlash take-up distance
 * (0 without BACKLASH; a reversal's correction ramps over it) and the thermal
 * reference temperature (0 without THERMAL; feeding it as the temperature
 * applies no thermal term). */
typedef struct {
    abbe_nm_t travel_min_nm;
    abbe_nm_t travel_max_nm;
    int32_t backlash_takeup_nm;
    int32_t thermal_tref_mdegc;
} abbe_axis_info_t;

/* Fill *info for axis (ABBE_AXIS_X..Z) of a loaded model. Returns ABBE_E_ARG
 * for NULL pointers or an axis out of range (*info untouched). */
abbe_status_t abbe_model_axis_info(const abbe_model_t *model, unsigned axis, abbe_axis_info_t *info);

/* sizeof(abbe_model_t) as this library was built: lets bindings in other
 * languages (host_tools/abbe/clib.py) check their copy of the layout. */
size_t abbe_model_sizeof(void);

/* CRC-32 as zlib computes it, continuing from crc (start with 0). Exposed for
 * ports that receive tables in chunks. */
uint32_t abbe_crc32(uint32_t crc, const void *data, size_t size);

#ifdef __cplusplus
} /* extern "C" */
#endif

#endif /* ABBE_MODEL_H */
