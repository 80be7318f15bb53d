"""The C library's structs as ctypes mirrors of ``lib/include/abbe/*.h``, field by
field (keep them in step with the headers): the 3-axis model and its evaluation's
inputs and outputs, the compensator, the five-axis evaluation's input and output.

:func:`abbe.model.clib.library.load_library` refuses a library whose ``abbe_model_t``
or ``abbe_comp_t`` has another size than these mirrors, since the binding allocates
them itself.
"""

from __future__ import annotations

import ctypes as C
import platform

import numpy as np

ABBE_AXES = 3
ABBE_TERMS = 6
ABBE_BLOCKS = 2
# abbe_model_t has the x86-64-v3 phase lanes on x86-64 only (model.h, ABBE_MODEL_X86_64_LANES)
_X86_64 = platform.machine().lower() in ("x86_64", "amd64") and C.sizeof(C.c_void_p) == 8
DIR_Q30_ONE = 1 << 30


class AxisModel(C.Structure):
    """abbe_axis_model_t (private fields, mirrored for the size and layout)."""
    _fields_ = [
        ("coef_q", C.c_void_p),
        ("coef_f32", C.c_void_p),
        ("freq", C.c_uint64 * ABBE_BLOCKS),
        ("phase_min", C.c_uint64 * ABBE_BLOCKS),
        ("takeup_rate_q46", C.c_uint64),
        ("travel_min_nm", C.c_int32),
        ("travel_max_nm", C.c_int32),
        ("span_nm", C.c_uint32),
        ("cheb_mul", C.c_uint32),
        ("backlash_reversal_q8", C.c_int32),
        ("backlash_takeup_nm", C.c_int32),
        ("thermal_expansion_q50", C.c_int32),
        ("thermal_offset_q16", C.c_int32),
        ("thermal_tref_mdegc", C.c_int32),
        ("cheb_shift", C.c_uint8),
        ("term_mask", C.c_uint8),
        ("n_terms", C.c_uint8),
        ("trend_rows", C.c_uint8),
        ("harmonics", C.c_uint8 * ABBE_BLOCKS),
        ("n_basis", C.c_uint8),
        ("column", C.c_uint8 * ABBE_TERMS),
        ("reversal_rows", C.c_uint8),
    ]


class Model(C.Structure):
    """abbe_model_t."""
    _fields_ = [
        ("blob", C.c_void_p),
        ("size", C.c_uint32),
        ("crc", C.c_uint32),
        ("features", C.c_uint32),
        ("version_major", C.c_uint16),
        ("version_minor", C.c_uint16),
        ("reference_nm", C.c_int32 * ABBE_AXES),
        ("tool_offset_nm", C.c_int32 * ABBE_AXES),
        ("squareness_q36", C.c_int32 * 3),
        ("square_const_q36", C.c_int64 * 2),
        ("ref_half_nm", C.c_int32 * 4),
        ("lane_min_nm", C.c_int32 * 4),
        ("lane_max_nm", C.c_int32 * 4),
        ("lane_span_nm", C.c_uint32 * 4),
        ("lane_cheb_shift", C.c_uint32 * 4),
        ("lane_cheb_mul", C.c_uint32 * 4),
        ("tool_half_nm", C.c_float * 4),
        ("squareness_f", C.c_float * 3),
        ("square_dx_dy", C.c_float * 4),
        ("square_dx_f", C.c_float * 4),
        *([("lane_freq", (C.c_uint64 * 4) * ABBE_BLOCKS), ("lane_phase_min", (C.c_uint64 * 4) * ABBE_BLOCKS)]
          if _X86_64 else []),
        ("any_block1", C.c_uint8),
        ("simd", C.c_uint8),
        ("axis", AxisModel * ABBE_AXES),
    ]


class InputF32(C.Structure):
    _fields_ = [("pos_mm", C.c_float * ABBE_AXES), ("dir_state", C.c_float * ABBE_AXES),
                ("temp_c", C.c_float * ABBE_AXES)]


class ErrorF32(C.Structure):
    _fields_ = [("error_um", C.c_float * ABBE_AXES), ("flags", C.c_uint32)]


class InputQ(C.Structure):
    _fields_ = [("pos_nm", C.c_int32 * ABBE_AXES), ("dir_state_q30", C.c_int32 * ABBE_AXES),
                ("temp_mdegc", C.c_int32 * ABBE_AXES)]


class ErrorQ(C.Structure):
    _fields_ = [("error_nm", C.c_int32 * ABBE_AXES), ("flags", C.c_uint32)]


class CompConfig(C.Structure):
    _fields_ = [
        ("warn_nm", C.c_int32 * ABBE_AXES),
        ("limit_nm", C.c_int32 * ABBE_AXES),
        ("rate_nm_per_cycle", C.c_int32 * ABBE_AXES),
        ("fade_cycles", C.c_uint16),
        ("stale_cycles", C.c_uint16),
        ("axis_sign", C.c_int8 * ABBE_AXES),
    ]


class CompInputF32(C.Structure):
    _fields_ = [("pos_mm", C.c_float * ABBE_AXES), ("temp_c", C.c_float * ABBE_AXES),
                ("dir", C.c_int8 * ABBE_AXES), ("fresh", C.c_uint8),
                ("axis_fault_mask", C.c_uint8)]


class CompInputQ(C.Structure):
    _fields_ = [("pos_nm", C.c_int32 * ABBE_AXES), ("temp_mdegc", C.c_int32 * ABBE_AXES),
                ("dir", C.c_int8 * ABBE_AXES), ("fresh", C.c_uint8),
                ("axis_fault_mask", C.c_uint8)]


class CompOutput(C.Structure):
    _fields_ = [("corr_nm", C.c_int32 * ABBE_AXES), ("target_nm", C.c_int32 * ABBE_AXES),
                ("flags", C.c_uint32), ("state", C.c_int)]


class CompStats(C.Structure):
    _fields_ = [("cycles", C.c_uint32), ("invalid_inputs", C.c_uint32),
                ("stale_events", C.c_uint32), ("limit_trips", C.c_uint32),
                ("rate_limited", C.c_uint32), ("model_swaps", C.c_uint32)]


class Comp(C.Structure):
    """abbe_comp_t."""
    _fields_ = [
        ("cfg", CompConfig),
        ("model", C.c_void_p),
        ("pending", C.c_void_p),
        ("gain_step_q16", C.c_uint32),
        ("gain_q16", C.c_uint32 * ABBE_AXES),
        ("out_nm", C.c_int32 * ABBE_AXES),
        ("target_nm", C.c_int32 * ABBE_AXES),
        ("fault_from_nm", C.c_int32 * ABBE_AXES),
        ("last_pos_nm", C.c_int32 * ABBE_AXES),
        ("dir_state_q30", C.c_int32 * ABBE_AXES),
        ("eval_flags", C.c_uint32),
        ("stale_count", C.c_uint16),
        ("have_pos", C.c_uint8),
        ("enabled", C.c_uint8),
        ("fault", C.c_uint8),
        ("stale", C.c_uint8),
        ("stats", CompStats),
        # a union in C (the fixed-point cycles' int32 words, the five-axis _f32 cycle's
        # working memory): the same 84 bytes, never read from Python
        ("scratch", C.c_int32 * (ABBE_AXES * ABBE_TERMS + ABBE_AXES)),
    ]


COMP_STATES = {0: "OFF", 1: "ON", 2: "FAULT"}

# numpy views of abbe_error_f32_t / abbe_error_q_t rows for the batch calls
_ERROR_F32_DTYPE = np.dtype([("error_um", np.float32, (ABBE_AXES,)), ("flags", np.uint32)])
_ERROR_Q_DTYPE = np.dtype([("error_nm", np.int32, (ABBE_AXES,)), ("flags", np.uint32)])
assert _ERROR_F32_DTYPE.itemsize == C.sizeof(ErrorF32) and _ERROR_Q_DTYPE.itemsize == C.sizeof(ErrorQ)


class FiveInputF32(C.Structure):
    """abbe_five_input_f32_t."""
    _fields_ = [("pos_mm", C.c_float * 3), ("angle_deg", C.c_float * 2),
                ("dir_state", C.c_float * 3), ("temp_c", C.c_float * 3)]


class FiveErrorF32(C.Structure):
    """abbe_five_error_f32_t."""
    _fields_ = [("error_um", C.c_float * 3), ("orient_urad", C.c_float * 3), ("flags", C.c_uint32)]
