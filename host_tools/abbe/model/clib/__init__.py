"""ctypes binding to the abbe C library (``libabbe.so``), by concern:

- :mod:`~abbe.model.clib.library`: finding and loading the shared object
  (``$ABBE_LIB``, the installed package, the checkout's ``build/lib/``; see
  :mod:`abbe.paths`), typing its calls, status codes and flags;
- :mod:`~abbe.model.clib.structs`: the ctypes mirrors of ``lib/include/abbe/*.h``;
- :mod:`~abbe.model.clib.three_axis`: :class:`CModel` (3-axis load and evaluation),
  :func:`crc32`;
- :mod:`~abbe.model.clib.five_axis`: :class:`CFiveModel`;
- :mod:`~abbe.model.clib.compensator`: :class:`CCompensator`;
- :mod:`~abbe.model.clib.thermal`: :class:`CThermal`, :func:`thermal_load_status`.

Every name is re-exported here, so ``from abbe.model import clib`` and
``clib.CModel`` stay the one way in; the modules import each other one way
(structs < library < three_axis < compensator; five_axis and thermal beside),
never this package.

Units as in the C API: the ``_f32`` variant takes mm / deg C and returns um
(urad for angular terms); the ``_q`` variant takes nm / Q30 / m°C and returns
nm (pm / prad for single terms).
"""

from __future__ import annotations

from abbe.model.clib.compensator import CCompensator
from abbe.model.clib.five_axis import CFiveModel
from abbe.model.clib.library import (FLAG_INPUT_INVALID, FLAG_OUT_OF_TRAVEL, FLAG_SATURATED,
                                     STATUS_NAMES, LibraryNotFound, available, library_path,
                                     load_library, status_name)
from abbe.model.clib.structs import (ABBE_AXES, ABBE_BLOCKS, ABBE_TERMS, COMP_STATES, DIR_Q30_ONE,
                                     AxisModel, Comp, CompConfig, CompInputF32, CompInputQ,
                                     CompOutput, CompStats, ErrorF32, ErrorQ, FiveErrorF32,
                                     FiveInputF32, InputF32, InputQ, Model)
from abbe.model.clib.thermal import CThermal, thermal_load_status
from abbe.model.clib.three_axis import CModel, crc32

__all__ = [
    "ABBE_AXES", "ABBE_BLOCKS", "ABBE_TERMS", "COMP_STATES", "DIR_Q30_ONE", "FLAG_INPUT_INVALID",
    "FLAG_OUT_OF_TRAVEL", "FLAG_SATURATED", "STATUS_NAMES", "AxisModel", "CCompensator",
    "CFiveModel", "CModel", "CThermal", "Comp", "CompConfig", "CompInputF32", "CompInputQ",
    "CompOutput", "CompStats", "ErrorF32", "ErrorQ", "FiveErrorF32", "FiveInputF32", "InputF32",
    "InputQ", "LibraryNotFound", "Model", "available", "crc32", "library_path", "load_library",
    "status_name", "thermal_load_status",
]
