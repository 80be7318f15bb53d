# abbe: volumetric error compensation for Klipper, through the abbe C library.
#
# Copyright 2026 the abbe authors. Licensed under the Apache License 2.0
# (LICENSE at the top of the abbe repository). Klipper is GPL-3.0-or-later;
# Apache-2.0 code may be combined into a GPL-3.0 work.
#
# Install: link this file into Klipper's klippy/extras/ as abbe.py
# (port/klipper/install.sh does it) and add an [abbe] section
# (docs/klipper.md). The model is evaluated by libabbe.so (ctypes), the same
# compensator (abbe_comp_step_f32) that runs in the LinuxCNC and grblHAL
# ports: there is no second implementation of the model here, only the
# splitting of moves, the position bookkeeping and the G-code commands.
#
# The transform chain, outermost first:
#   G-code -> [abbe] -> [skew_correction] -> [bed_mesh] -> toolhead
# abbe takes the programmed point p, commands p + c(p) (c = -E(p), the
# compensator's correction) to the next transform, and hands p (never the
# corrected position) back to the G-code layer.
import ctypes
import ctypes.util
import logging
import math
import os

AXES = 3
ABBE_OK = 0
FEATURE_SQUARENESS = 0x1
FLAG_LIMIT = 0x0020
COMP_OFF, COMP_ON, COMP_FAULT = 0, 1, 2


class _CompConfig(ctypes.Structure):
    _fields_ = [("warn_nm", ctypes.c_int32 * AXES),
                ("limit_nm", ctypes.c_int32 * AXES),
                ("rate_nm_per_cycle", ctypes.c_int32 * AXES),
                ("fade_cycles", ctypes.c_uint16),
                ("stale_cycles", ctypes.c_uint16),
                ("axis_sign", ctypes.c_int8 * AXES)]


class _CompInput(ctypes.Structure):
    _fields_ = [("pos_mm", ctypes.c_float * AXES),
                ("temp_c", ctypes.c_float * AXES),
                ("dir", ctypes.c_int8 * AXES),
                ("fresh", ctypes.c_uint8),
                ("axis_fault_mask", ctypes.c_uint8)]


class _CompOutput(ctypes.Structure):
    _fields_ = [("corr_nm", ctypes.c_int32 * AXES),
                ("target_nm", ctypes.c_int32 * AXES),
                ("flags", ctypes.c_uint32),
                ("state", ctypes.c_int)]


class _Input(ctypes.Structure):
    _fields_ = [("pos_mm", ctypes.c_float * AXES),
                ("dir_state", ctypes.c_float * AXES),
                ("temp_c", ctypes.c_float * AXES)]


class _Error(ctypes.Structure):
    _fields_ = [("error_um", ctypes.c_float * AXES),
                ("flags", ctypes.c_uint32)]


class AbbeLibraryError(Exception):
    pass


def _aligned_buffer(nbytes):
    """Zeroed memory of nbytes, 8-byte aligned (the library's structs and the
    table's in-place float loads need 4)."""
    return (ctypes.c_uint64 * ((nbytes + 7) // 8))()


class AbbeLibrary:
    """libabbe.so with the few functions this module calls, typed."""

    def __init__(self, path):
        if not path:
            path = os.environ.get("ABBE_LIB") or ctypes.util.find_library("abbe")
        if not path:
            raise AbbeLibraryError(
                "libabbe.so not found: set 'library' in [abbe] or $ABBE_LIB")
        try:
            lib = ctypes.CDLL(path)
        except OSError as exc:
            raise AbbeLibraryError("cannot load %s: %s" % (path, exc))
        P = ctypes.POINTER
        sigs = {
            "abbe_strerror": (ctypes.c_char_p, [ctypes.c_int]),
            "abbe_model_sizeof": (ctypes.c_size_t, []),
            "abbe_comp_sizeof": (ctypes.c_size_t, []),
            "abbe_model_load": (ctypes.c_int, [ctypes.c_void_p, ctypes.c_void_p,
                                               ctypes.c_size_t]),
            "abbe_model_crc": (ctypes.c_uint32, [ctypes.c_void_p]),
            "abbe_model_features": (ctypes.c_uint32, [ctypes.c_void_p]),
            "abbe_error_eval_batch_f32": (ctypes.c_int, [ctypes.c_void_p, ctypes.c_size_t,
                                                         P(_Input), P(_Error)]),
            "abbe_comp_init": (ctypes.c_int, [ctypes.c_void_p, P(_CompConfig),
                                              ctypes.c_void_p]),
            "abbe_comp_enable": (ctypes.c_int, [ctypes.c_void_p]),
            "abbe_comp_disable": (ctypes.c_int, [ctypes.c_void_p]),
            "abbe_comp_reset": (ctypes.c_int, [ctypes.c_void_p]),
            "abbe_comp_swap_model": (ctypes.c_int, [ctypes.c_void_p, ctypes.c_void_p]),
            "abbe_comp_step_f32": (ctypes.c_int, [ctypes.c_void_p, P(_CompInput),
                                                  P(_CompOutput)]),
        }
        for name, sig in sigs.items():
            try:
                fn = getattr(lib, name)
            except AttributeError:
                raise AbbeLibraryError("%s does not export %s" % (path, name))
            fn.restype, fn.argtypes = sig
        self.lib = lib
        self.path = path
        self.model_size = lib.abbe_model_sizeof()
        self.comp_size = lib.abbe_comp_sizeof()

    def strerror(self, status):
        return self.lib.abbe_strerror(status).decode("ascii", "replace")


class LoadedTable:
    """A validated table: its bytes (kept alive: the model points into them),
    the model struct, its travel and the split length derived from it."""

    def __init__(self, lib, path, blob):
        self.path = path
        self.blob_mem = _aligned_buffer(len(blob))
        ctypes.memmove(self.blob_mem, blob, len(blob))
        self.model = _aligned_buffer(lib.model_size)
        status = lib.lib.abbe_model_load(self.model, self.blob_mem, len(blob))
        if status != ABBE_OK:
            raise AbbeLibraryError("table %s refused by the abbe library: %s (status %d)"
                                   % (path, lib.strerror(status), status))
        self.crc = lib.lib.abbe_model_crc(self.model)
        self.features = lib.lib.abbe_model_features(self.model)
        self.travel = _travel_from_blob(blob)

    def errors_um(self, lib, points):
        """dX, dY, dZ (um) at each point (mm), direction state 0, through the
        library's batch evaluation."""
        n = len(points)
        inp = (_Input * n)()
        out = (_Error * n)()
        for i, p in enumerate(points):
            for a in range(AXES):
                inp[i].pos_mm[a] = p[a]
                inp[i].temp_c[a] = 20.0
        status = lib.lib.abbe_error_eval_batch_f32(self.model, n, inp, out)
        if status != ABBE_OK:
            raise AbbeLibraryError("evaluation failed: %s" % lib.strerror(status))
        return [[out[i].error_um[a] for a in range(AXES)] for i in range(n)]

    def curvature_um_per_mm2(self, lib):
        """kappa, um/mm^2: a bound on the second derivative of the error along any
        line, from the table, INSIDE the travel only (outside it the table holds its
        end values: that kink is not curvature a segment must follow).

        Two passes, both through the library: (1) second differences at a step of
        span/400 along lines parallel to each axis through the corners and the
        centre of the other two (the one-axis terms' curvature, finely); (2) on a
        5 x 5 x 5 grid, the whole Hessian of dX, dY, dZ (mixed partials by the
        four-point stencil) and its largest Gershgorin row sum, which bounds
        u^T H u for every unit direction u (the lever-arm products' cross terms).
        The larger of the two is kappa."""
        lo = [t[0] for t in self.travel]
        hi = [t[1] for t in self.travel]
        mid = [(lo[a] + hi[a]) / 2.0 for a in range(AXES)]
        kappa = 0.0
        n = 401
        for a in range(AXES):
            h = (hi[a] - lo[a]) / (n - 1)
            b, c = [k for k in range(AXES) if k != a]
            pts = []
            for u in (lo[b], mid[b], hi[b]):
                for v in (lo[c], mid[c], hi[c]):
                    for i in range(n):
                        p = [0.0] * AXES
                        p[a], p[b], p[c] = lo[a] + i * h, u, v
                        pts.append(p)
            err = self.errors_um(lib, pts)
            for line in range(9):
                e = err[line * n:(line + 1) * n]
                for i in range(1, n - 1):
                    for k in range(AXES):
                        d2 = abs(e[i + 1][k] - 2.0 * e[i][k] + e[i - 1][k]) / (h * h)
                        kappa = max(kappa, d2)
        # (2) the whole Hessian at interior grid points
        hs = [(hi[a] - lo[a]) / 400.0 for a in range(AXES)]
        centres = []
        for i in range(5):
            for j in range(5):
                for k in range(5):
                    centres.append([lo[0] + (hi[0] - lo[0]) * (0.1 + 0.2 * i),
                                    lo[1] + (hi[1] - lo[1]) * (0.1 + 0.2 * j),
                                    lo[2] + (hi[2] - lo[2]) * (0.1 + 0.2 * k)])
        offsets = [(0, 0, 0)]
        for a in range(AXES):
            for sa in (-1, 1):
                o = [0, 0, 0]
                o[a] = sa
                offsets.append(tuple(o))
        for a in range(AXES):
            for b in range(a + 1, AXES):
                for sa in (-1, 1):
                    for sb in (-1, 1):
                        o = [0, 0, 0]
                        o[a], o[b] = sa, sb
                        offsets.append(tuple(o))
        pts = [[c[x] + o[x] * hs[x] for x in range(AXES)] for c in centres for o in offsets]
        err = self.errors_um(lib, pts)
        m = len(offsets)
        index = {o: i for i, o in enumerate(offsets)}
        for ci in range(len(centres)):
            e = err[ci * m:(ci + 1) * m]
            for comp in range(AXES):
                hess = [[0.0] * AXES for _ in range(AXES)]
                for a in range(AXES):
                    plus = [0, 0, 0]
                    plus[a] = 1
                    minus = [0, 0, 0]
                    minus[a] = -1
                    hess[a][a] = (e[index[tuple(plus)]][comp] - 2.0 * e[0][comp]
                                  + e[index[tuple(minus)]][comp]) / (hs[a] * hs[a])
                for a in range(AXES):
                    for b in range(a + 1, AXES):
                        def at(sa, sb):
                            o = [0, 0, 0]
                            o[a], o[b] = sa, sb
                            return e[index[tuple(o)]][comp]
                        v = (at(1, 1) - at(1, -1) - at(-1, 1) + at(-1, -1)) / (4.0 * hs[a] * hs[b])
                        hess[a][b] = hess[b][a] = v
                for a in range(AXES):
                    kappa = max(kappa, sum(abs(hess[a][b]) for b in range(AXES)))
        return kappa


def _travel_from_blob(blob):
    """Per-axis (min, max) travel in mm from the axis records (docs/table-format.md:
    record a at 64 + 64 a, travel_min_nm / travel_max_nm the first two i32)."""
    out = []
    for a in range(AXES):
        off = 64 + 64 * a
        tmin = int.from_bytes(blob[off:off + 4], "little", signed=True)
        tmax = int.from_bytes(blob[off + 4:off + 8], "little", signed=True)
        out.append((tmin * 1e-6, tmax * 1e-6))
    return out


class AbbeCompensation:
    def __init__(self, config):
        self.printer = config.get_printer()
        self.gcode = self.printer.lookup_object("gcode")
        self.table_path = config.get("table")
        self.enabled_at_start = config.getboolean("enable", True)
        self.max_correction_um = config.getfloat("max_correction", 200.0, above=0.0)
        self.bound_um = config.getfloat("split_bound", 1.0, minval=0.01, maxval=100.0)
        self.min_split_mm = config.getfloat("min_split", 0.5, above=0.0)
        self.max_split_mm = config.getfloat("max_split", 50.0, above=0.0)
        self.rate_um = config.getfloat("max_change_per_segment", 10.0, above=0.0)
        self.fade_segments = config.getint("fade_segments", 32, minval=1, maxval=65535)
        self.temperature_c = config.getfloat("temperature", 20.0)
        if self.max_split_mm < self.min_split_mm:
            raise config.error("[abbe] max_split must be >= min_split")
        try:
            self.lib = AbbeLibrary(config.get("library", None))
            self.table = self._load_table(self.table_path)
            self._check_correction_size(self.table)
        except (AbbeLibraryError, OSError) as exc:
            raise config.error("[abbe] %s" % (exc,))
        self.split_mm = self._split_length(self.table)
        self.comp = _aligned_buffer(self.lib.comp_size)
        cfg = _CompConfig()
        limit_nm = int(round(self.max_correction_um * 1000.0))
        for a in range(AXES):
            cfg.warn_nm[a] = max(1, limit_nm // 2)
            cfg.limit_nm[a] = limit_nm
            cfg.rate_nm_per_cycle[a] = max(1, int(round(self.rate_um * 1000.0)))
            cfg.axis_sign[a] = 1
        cfg.fade_cycles = self.fade_segments
        cfg.stale_cycles = 65535
        self.comp_config = cfg
        status = self.lib.lib.abbe_comp_init(self.comp, ctypes.byref(cfg), self.table.model)
        if status != ABBE_OK:
            raise config.error("[abbe] compensator refused the configuration: %s"
                               % self.lib.strerror(status))
        self.spare = None          # the table a swap replaced (kept until the next one)
        self.enabled = False
        self.corr_mm = [0.0, 0.0, 0.0]
        self.last_flags = 0
        self.state = COMP_OFF
        self.last_position = [0.0, 0.0, 0.0, 0.0]
        self.next_transform = None
        self.segments = 0
        self.printer.register_event_handler("klippy:ready", self._handle_ready)
        for name, fn, desc in (
                ("ABBE_STATUS", self.cmd_ABBE_STATUS, "Report abbe's compensation state"),
                ("ABBE_ENABLE", self.cmd_ABBE_ENABLE,
                 "Enable abbe's compensation (fades in over fade_segments)"),
                ("ABBE_DISABLE", self.cmd_ABBE_DISABLE,
                 "Disable abbe's compensation (fades out over fade_segments)"),
                ("ABBE_LOAD", self.cmd_ABBE_LOAD,
                 "Load a new abbe table (TABLE=path); it takes over at the next move")):
            self.gcode.register_command(name, fn, desc=desc)

    # -- tables ------------------------------------------------------------
    def _load_table(self, path):
        path = os.path.expanduser(path)
        with open(path, "rb") as f:
            blob = f.read(1 << 20)
        return LoadedTable(self.lib, path, blob)

    def _split_length(self, table):
        kappa = table.curvature_um_per_mm2(self.lib)
        self.kappa = kappa
        if kappa <= 0.0:
            return self.max_split_mm
        length = math.sqrt(8.0 * self.bound_um / kappa)
        return min(self.max_split_mm, max(self.min_split_mm, length))

    def _check_correction_size(self, table):
        """Refuse a table whose error inside its travel exceeds max_correction:
        the compensator would trip its limit in the middle of a print."""
        lo = [t[0] for t in table.travel]
        hi = [t[1] for t in table.travel]
        pts = []
        for i in range(5):
            for j in range(5):
                for k in range(5):
                    pts.append([lo[0] + (hi[0] - lo[0]) * i / 4.0,
                                lo[1] + (hi[1] - lo[1]) * j / 4.0,
                                lo[2] + (hi[2] - lo[2]) * k / 4.0])
        worst = max(abs(v) for e in table.errors_um(self.lib, pts) for v in e)
        if worst > self.max_correction_um:
            raise AbbeLibraryError(
                "table %s asks for corrections up to %.1f um, above max_correction = %.1f um"
                % (table.path, worst, self.max_correction_um))

    # -- the transform -----------------------------------------------------
    def _handle_ready(self):
        # Registered last (after bed_mesh at config time and skew_correction at
        # connect): abbe is the outermost transform, so it sees the programmed point.
        gcode_move = self.printer.lookup_object("gcode_move")
        self.next_transform = gcode_move.set_move_transform(self, force=True)
        if self.enabled_at_start:
            try:
                self._refuse_double_compensation()
                self._enable()
            except self.printer.command_error as exc:
                logging.error("%s: abbe stays disabled", exc)
                self.gcode.respond_info("%s: abbe stays disabled" % (exc,))
        gcode_move.reset_last_position()

    def _refuse_double_compensation(self):
        """The same effect must not be compensated twice: a table with squareness
        and a non-zero [skew_correction] would both correct the skew."""
        skew = self.printer.lookup_object("skew_correction", None)
        if skew is None or not (self.table.features & FEATURE_SQUARENESS):
            return
        factors = (skew.xy_factor, skew.xz_factor, skew.yz_factor)
        if any(f != 0.0 for f in factors):
            raise self.printer.command_error(
                "abbe: the table corrects squareness and [skew_correction] has a skew "
                "loaded (%s): clear one (SET_SKEW CLEAR=1) before enabling abbe" % (factors,))

    def _active(self):
        return self.enabled or self.state != COMP_OFF or any(self.corr_mm)

    def get_position(self):
        pos = list(self.next_transform.get_position())
        for a in range(AXES):
            pos[a] -= self.corr_mm[a]
        self.last_position[:] = pos
        return pos

    def _step(self, p, dirs):
        inp = _CompInput()
        for a in range(AXES):
            inp.pos_mm[a] = p[a]
            inp.temp_c[a] = self.temperature_c
            inp.dir[a] = dirs[a]
        inp.fresh = 1
        out = _CompOutput()
        self.lib.lib.abbe_comp_step_f32(self.comp, ctypes.byref(inp), ctypes.byref(out))
        self.corr_mm = [out.corr_nm[a] * 1e-6 for a in range(AXES)]
        self.last_flags = out.flags
        self.state = out.state
        self.segments += 1

    def move(self, newpos, speed):
        if not self._active():
            # off and faded out: stock Klipper, the move passed on untouched
            self.next_transform.move(newpos, speed)
            self.last_position[:] = newpos
            return
        start = self.last_position
        delta = [newpos[i] - start[i] for i in range(len(newpos))]
        dist = math.sqrt(sum(d * d for d in delta[:AXES]))
        dirs = [(d > 0.0) - (d < 0.0) for d in delta[:AXES]]
        n = max(1, int(math.ceil(dist / self.split_mm - 1e-9)))
        for i in range(1, n + 1):
            f = float(i) / n
            p = newpos if i == n else [start[k] + delta[k] * f for k in range(len(newpos))]
            self._step(p, dirs)
            self.next_transform.move([p[a] + self.corr_mm[a] for a in range(AXES)]
                                     + list(p[AXES:]), speed)
        self.last_position[:] = newpos
        if self.last_flags & FLAG_LIMIT:
            logging.error("abbe: correction limit tripped at %s: compensation fading out", newpos)

    # -- G-code commands ---------------------------------------------------
    def _enable(self):
        self.lib.lib.abbe_comp_enable(self.comp)
        self.enabled = True

    cmd_ABBE_STATUS_help = "Report abbe's compensation state"

    def cmd_ABBE_STATUS(self, gcmd):
        gcmd.respond_info(
            "abbe: %s, table %s (CRC %08X), state %s, flags 0x%04x, correction "
            "%.3f %.3f %.3f um, curvature %.4f um/mm^2, split %.3f mm (bound %.2f um), "
            "segments %d" % (
                "enabled" if self.enabled else "disabled", self.table.path, self.table.crc,
                ("OFF", "ON", "FAULT")[self.state] if 0 <= self.state <= 2 else self.state,
                self.last_flags, self.corr_mm[0] * 1e3, self.corr_mm[1] * 1e3,
                self.corr_mm[2] * 1e3, self.kappa, self.split_mm, self.bound_um, self.segments))

    def cmd_ABBE_ENABLE(self, gcmd):
        self._refuse_double_compensation()
        self._enable()
        gcmd.respond_info("abbe: enabled (fading in over %d segments)" % self.fade_segments)

    def cmd_ABBE_DISABLE(self, gcmd):
        self.lib.lib.abbe_comp_disable(self.comp)
        self.enabled = False
        gcmd.respond_info("abbe: disabled (fading out over %d segments)" % self.fade_segments)

    def cmd_ABBE_LOAD(self, gcmd):
        path = gcmd.get("TABLE")
        try:
            table = self._load_table(path)
            self._check_correction_size(table)
        except (AbbeLibraryError, OSError) as exc:
            raise gcmd.error("abbe: %s; the running table (CRC %08X) is kept"
                             % (exc, self.table.crc))
        status = self.lib.lib.abbe_comp_swap_model(self.comp, table.model)
        if status != ABBE_OK:
            raise gcmd.error("abbe: swap refused: %s; the running table is kept"
                             % self.lib.strerror(status))
        # the compensator takes the new model at its next step; the old one must
        # stay valid until then, so it is kept as the spare
        self.spare, self.table = self.table, table
        self.split_mm = self._split_length(table)
        gcmd.respond_info("abbe: table %s (CRC %08X) takes over at the next move"
                          % (path, table.crc))


def load_config(config):
    return AbbeCompensation(config)
