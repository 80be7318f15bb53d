"""Independent readers of every export format, written from the format descriptions
(docs/exports.md and the controllers' documentation it cites), not from the writers.

Each ``read_<target>(out_dir)`` parses the files as the controller would and returns
``corr(pos_mm (N, 3), state (N, 3)) -> (N, 3) um``: what the controller adds to the
commanded position (state: +1 after moving +, -1 after moving -). Eq. 3 for the ISG
reader is written out here from docs/table-format.md. Nothing is imported from
abbe.exports.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

AX = "XYZ"


class FormatError(AssertionError):
    pass


def _num(s: str) -> float:
    v = float(s)
    if not np.isfinite(v):
        raise FormatError(f"not finite: {s}")
    return v


def hold_interp(x, xp, fp):
    """Linear interpolation with the end values held."""
    return np.interp(np.asarray(x, float), np.asarray(xp, float), np.asarray(fp, float))


# --- LinuxCNC ------------------------------------------------------------------------

def load_comp_file(path: Path, comp_type: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """usrmotLoadComp: read "%lf %lf %lf" per line, stop at the first line that is not
    three numbers; type 0 columns are actual positions (trim = nominal - column), type 1
    the trims. Refuses what command.c refuses (more than 256, non-increasing nominals)."""
    nom, fwd, rev = [], [], []
    for line in path.read_text().splitlines():
        parts = line.split()
        try:
            n, f, r = (float(parts[0]), float(parts[1]), float(parts[2]))
        except (IndexError, ValueError):
            break
        nom.append(n)
        if comp_type == 0:
            fwd.append(n - f)
            rev.append(n - r)
        else:
            fwd.append(f)
            rev.append(r)
    if len(nom) > 256:
        raise FormatError("joint: too many compensation entries")
    if any(b <= a for a, b in zip(nom, nom[1:])):
        raise FormatError("compensation values must increase")
    # emcmot_comp_entry_t stores trims as float
    return (np.array(nom), np.array(fwd, dtype=np.float32).astype(float),
            np.array(rev, dtype=np.float32).astype(float))


def read_ini_comp(out: Path) -> dict[int, tuple[str, int]]:
    """[JOINT_n] COMP_FILE / COMP_FILE_TYPE of the INI snippet."""
    joints: dict[int, tuple[str, int]] = {}
    cur = None
    vals: dict[str, str] = {}
    for line in (out / "linuxcnc.ini").read_text().splitlines() + ["[END]"]:
        line = line.split("#")[0].strip()
        m = re.fullmatch(r"\[(\w+)\]", line)
        if m:
            if cur is not None:
                joints[cur] = (vals["COMP_FILE"], int(vals["COMP_FILE_TYPE"]))
            cur = int(m.group(1)[6:]) if m.group(1).startswith("JOINT_") else None
            vals = {}
        elif "=" in line:
            k, v = line.split("=", 1)
            vals[k.strip()] = v.strip()
    return joints


def read_linuxcnc_comp(out: Path, joint_axis=(0, 1, 2)):
    joints = read_ini_comp(out)
    tabs = {j: load_comp_file(out / name, typ) for j, (name, typ) in joints.items()}

    def corr(pos, state):
        res = np.zeros_like(pos, dtype=float)
        for j, (nom, fwd, rev) in tabs.items():
            k = joint_axis.index(j)
            f = hold_interp(pos[:, k], nom, fwd)
            r = hold_interp(pos[:, k], nom, rev)
            res[:, k] = np.where(state[:, k] > 0, f, r) * 1e3
        return res
    return corr, tabs


def read_matrixkins(out: Path):
    C = np.eye(3)
    for line in (out / "matrixkins.hal").read_text().splitlines():
        m = re.match(r"\s*setp\s+\S+\.C_([xyz])([xyz])\s+(\S+)", line)
        if m:
            C["xyz".index(m.group(1)), "xyz".index(m.group(2))] = _num(m.group(3))
    return lambda pos, state: (pos @ C.T - pos) * 1e3


# --- Klipper, Marlin -------------------------------------------------------------------

def read_klipper(out: Path, profile: str = "abbe"):
    sect, vals = None, {}
    for line in (out / "skew_correction.cfg").read_text().splitlines():
        line = line.split("#")[0].strip()
        if line.startswith("["):
            sect = line.strip("[]").strip()
        elif "=" in line and sect == f"skew_correction {profile}":
            k, v = line.split("=", 1)
            vals[k.strip()] = _num(v)
    xy, xz, yz = vals["xy_skew"], vals["xz_skew"], vals["yz_skew"]

    def corr(pos, state):
        x, y, z = pos.T
        moved = np.column_stack([x - y * xy - z * (xz - xy * yz), y - z * yz, z])
        return (moved - pos) * 1e3
    return corr


def read_klipper_twist(out: Path):
    """Klipper's [axis_twist_compensation] corrects probe readings, never the motion: the
    motion correction is zero. The values are parsed strictly here all the same (Klipper's
    config parser: z_compensations a comma list of floats, start < end)."""
    vals = {}
    for line in (out / "axis_twist_compensation.cfg").read_text().splitlines():
        line = line.split("#")[0].strip()
        if ":" in line and not line.startswith("["):
            k, v = line.split(":", 1)
            vals[k.strip()] = v.strip()
    comp = [_num(c) for c in vals["z_compensations"].split(",")]
    if len(comp) < 2 or not _num(vals["compensation_start_x"]) < _num(vals["compensation_end_x"]):
        raise FormatError("axis_twist_compensation: fewer than 2 values or start >= end")
    return lambda pos, state: np.zeros_like(np.asarray(pos, dtype=float))


def read_rrf_m556(out: Path):
    """From RepRapFirmware's Move::AxisTransform and the M556 page: tanXY = X/S,
    tanYZ = Y/S, tanXZ = Z/S; x += tanXY y + tanXZ z, y += tanYZ z (P0)."""
    words = None
    for line in (out / "rrf_m556.g").read_text().splitlines():
        line = line.split(";")[0].strip()
        if line.startswith("M556"):
            if words is not None:
                raise FormatError("two M556 lines")
            words = {w[0]: _num(w[1:]) for w in line.split()[1:]}
    if words is None or "S" not in words or words["S"] <= 0:
        raise FormatError("no M556 with S > 0")
    s = words["S"]
    txy, tyz, txz = words.get("X", 0.0) / s, words.get("Y", 0.0) / s, words.get("Z", 0.0) / s

    def corr(pos, state):
        x, y, z = pos.T
        moved = np.column_stack([x + txy * y + txz * z, y + tyz * z, z])
        return (moved - pos) * 1e3
    return corr


def read_marlin(out: Path):
    xy = xz = yz = 0.0
    back = {"X": 0.0, "Y": 0.0, "Z": 0.0}
    frac = 1.0
    for line in (out / "marlin.gcode").read_text().splitlines():
        line = line.split(";")[0].strip()
        words = dict((w[0], w[1:]) for w in line.split()[1:])
        if line.startswith("M852"):
            xy = _num(words.get("I", words.get("S", "0")))
            xz, yz = _num(words.get("J", "0")), _num(words.get("K", "0"))
        elif line.startswith("M425"):
            frac = _num(words.get("F", "1"))
            for a in AX:
                if a in words:
                    back[a] = _num(words[a])
    d = np.array([back[a] for a in AX]) * frac

    def corr(pos, state):
        x, y, z = pos.T
        moved = np.column_stack([x - y * xy - z * (xz - xy * yz), y - z * yz, z])
        # backlash.cpp: after a + move the extra distance is applied, after a - move not;
        # in between (the smoothing distance after a reversal) the share taken up so far,
        # with state ramping from -1 to +1 over it (docs/exports.md)
        share = np.clip(0.5 * (1.0 + np.asarray(state, float)), 0.0, 1.0)
        applied = share * d * np.where(d > 0, 1.0, 0.0)
        return (moved - pos + applied) * 1e3
    return corr


# --- Siemens ---------------------------------------------------------------------------

def read_sinumerik_lec(out: Path, names=("X1", "Y1", "Z1")):
    text = (out / "EEC.INI").read_text().splitlines()
    if text[0].strip() != "%_N_AX_EEC_INI" or text[-1].strip() != "M17":
        raise FormatError("not an %_N_AX_EEC_INI program ending M17")
    vals: dict[str, dict[int, float]] = {n: {} for n in names}
    par: dict[tuple[str, str], float] = {}
    for line in text:
        line = line.split(";")[0].strip()
        m = re.fullmatch(r"\$AA_ENC_COMP\[0,(\d+),(\w+)\]=(\S+)", line)
        if m:
            vals[m.group(2)][int(m.group(1))] = _num(m.group(3))
            continue
        m = re.fullmatch(r"\$AA_ENC_COMP_(STEP|MIN|MAX|IS_MODULO)\[0,(\w+)\]=(\S+)", line)
        if m:
            par[(m.group(2), m.group(1))] = _num(m.group(3))
    tabs = {}
    for k, n in enumerate(names):
        v = vals[n]
        N = max(v) + 1
        if sorted(v) != list(range(N)):
            raise FormatError(f"{n}: interpolation points missing")
        mn, st, mx = par[(n, "MIN")], par[(n, "STEP")], par[(n, "MAX")]
        if abs(mn + (N - 1) * st - mx) > 1e-6:
            raise FormatError(f"{n}: MAX != MIN + (N - 1) STEP")
        tabs[k] = (mn + st * np.arange(N), np.array([v[i] for i in range(N)]))

    def corr(pos, state):
        res = np.zeros_like(pos, dtype=float)
        for k, (xp, fp) in tabs.items():
            res[:, k] = -hold_interp(pos[:, k], xp, fp) * 1e3  # positive value: axis moves -
        return res
    return corr


def read_sinumerik_cec(out: Path, names=("X1", "Y1", "Z1")):
    text = (out / "CEC.INI").read_text().splitlines()
    if text[0].strip() != "%_N_NC_CEC_INI" or text[-1].strip() != "M17":
        raise FormatError("not an %_N_NC_CEC_INI program ending M17")
    vals: dict[int, dict[int, float]] = {}
    par: dict[int, dict[str, str]] = {}
    for line in text:
        line = line.split(";")[0].strip()
        m = re.fullmatch(r"\$AN_CEC\[(\d+),(\d+)\]=(\S+)", line)
        if m:
            vals.setdefault(int(m.group(1)), {})[int(m.group(2))] = _num(m.group(3))
            continue
        m = re.fullmatch(r"\$AN_CEC_(\w+)\[(\d+)\]=(\S+)", line)
        if m:
            par.setdefault(int(m.group(2)), {})[m.group(1)] = m.group(3)
    tabs = []
    for t, v in vals.items():
        p = par[t]
        N = max(v) + 1
        mn, st, mx = _num(p["MIN"]), _num(p["STEP"]), _num(p["MAX"])
        if abs(mn + (N - 1) * st - mx) > 1e-6:
            raise FormatError(f"table {t}: MAX != MIN + (N - 1) STEP")
        i = names.index(p["INPUT_AXIS"].strip("()"))
        o = names.index(p["OUTPUT_AXIS"].strip("()"))
        tabs.append((i, o, int(p["DIRECTION"]), mn + st * np.arange(N),
                     np.array([v[n] for n in range(N)])))

    def corr(pos, state):
        res = np.zeros_like(pos, dtype=float)
        for i, o, d, xp, fp in tabs:
            val = hold_interp(pos[:, i], xp, fp)
            if d:
                val = np.where(np.sign(state[:, i]) == d, val, 0.0)
            res[:, o] -= val * 1e3
        return res
    return corr, tabs


# --- Heidenhain ------------------------------------------------------------------------

def read_tnc_table(path: Path) -> tuple[list[str], list[list[str]]]:
    lines = [ln.rstrip() for ln in path.read_text().splitlines()]
    if not lines[0].startswith("BEGIN ") or lines[-1] != "[END]":
        raise FormatError(f"{path.name}: not a TNC table (BEGIN ... [END])")
    cols = lines[1].split()
    rows = [ln.split() for ln in lines[2:-1]]
    for r in rows:
        if len(r) != len(cols):
            raise FormatError(f"{path.name}: a row with {len(r)} cells for {len(cols)} columns")
    return cols, rows


def read_heidenhain(out: Path, limit: int = 256):
    ccols, crows = read_tnc_table(out / "CONFIG.CMA")
    active = [r for r in crows if r[ccols.index("ACTIVE")] == "*"]
    if len(active) != 1:
        raise FormatError("exactly one active line in the .CMA")
    tabs = []
    for a in AX:
        if a not in ccols:
            continue
        cols, rows = read_tnc_table(out / active[0][ccols.index(a)])
        if len(rows) > limit:
            raise FormatError("more than 256 entries")
        data = np.array([[_num(v) for v in r] for r in rows])
        pos = data[:, cols.index("AXISPOS")]
        outs = {b: data[:, cols.index(b)] for b in AX if b in cols}
        bl = data[:, cols.index("BACKLASH")] if "BACKLASH" in cols else None
        tabs.append((AX.index(a), pos, outs, bl))

    def corr(p, state):
        res = np.zeros_like(p, dtype=float)
        for i, pos, outs, bl in tabs:
            for b, col in outs.items():
                k = AX.index(b)
                v = hold_interp(p[:, i], pos, col)
                if k == i and bl is not None:  # negative traverse: value + BACKLASH
                    v = v + np.where(state[:, i] < 0, hold_interp(p[:, i], pos, bl), 0.0)
                res[:, k] -= v * 1e3
        return res
    return corr


# --- Fanuc -----------------------------------------------------------------------------

def read_fanuc(out: Path, unit_um: float = 1.0, reference=(0.0, 0.0, 0.0),
               ref_return=(1, 1, 1)):
    lines = (out / "fanuc_pitch.prm").read_text().split()
    if lines[0] != "%" or lines[-1] != "%":
        raise FormatError("tape must start and end with %")
    par: dict[int, dict[int, int]] = {}
    data: dict[int, int] = {}
    for w in lines[1:-1]:
        m = re.fullmatch(r"N(\d+)((?:A\d+P-?\d+)+|P-?\d+)", w)
        if not m:
            raise FormatError(f"bad tape word {w}")
        no = int(m.group(1))
        if no >= 10000:
            data[no - 10000] = int(m.group(2)[1:])
        else:
            par[no] = {int(a): (int(v, 2) if no == 3605 else int(v))
                       for a, v in re.findall(r"A(\d+)P(-?\d+)", m.group(2))}
    axes = []
    for k in range(3):
        A = k + 1
        nref, nmin, nmax = par[3620][A], par[3621][A], par[3622][A]
        mag, iv = par[3623][A], par[3624][A]
        h = iv * unit_um / 1000.0
        bidir = bool(par[3605][A] & 1)

        def absolute(first: int, at_ref: float):
            # Q(n): cumulative increments from the reference point
            Q = {nref: at_ref}
            for n in range(nref + 1, nmax + 1):
                Q[n] = Q[n - 1] + data[first + n - nmin] * mag * unit_um
            for n in range(nref, nmin - 1, -1):
                Q[n - 1] = Q[n] - data[first + n - nmin] * mag * unit_um
            return Q
        plus = absolute(nmin, 0.0)
        minus = None
        if bidir:
            minus = absolute(par[3626][A], par[3627][A] * unit_um)
            if ref_return[k] < 0:
                plus, minus = absolute(nmin, par[3627][A] * unit_um), absolute(par[3626][A], 0.0)
        axes.append((reference[k], h, nref, nmin, nmax, plus, minus))

    def stair(p, r, h, nref, nmin, nmax, Q):
        k = (p - r) / h
        n = nref + np.where(k >= 0, np.floor(k + 1e-9), np.ceil(k - 1e-9)).astype(int)
        n = np.clip(n, nmin - 1, nmax)
        return np.array([Q[int(i)] for i in n])

    def corr(pos, state):
        res = np.zeros_like(pos, dtype=float)
        for k, (r, h, nref, nmin, nmax, plus, minus) in enumerate(axes):
            u = stair(pos[:, k], r, h, nref, nmin, nmax, plus)
            if minus is None:
                res[:, k] = u
            else:
                d = stair(pos[:, k], r, h, nref, nmin, nmax, minus)
                res[:, k] = np.where(state[:, k] < 0, d, u)
        return res
    return corr


# --- Beckhoff ISG CSV ------------------------------------------------------------------

def read_isg_blocks(path: Path) -> list[tuple[list[str], np.ndarray]]:
    """Blocks of an ISG CSV file: '//' comments, '#' starts a block, a header, records."""
    blocks, header, rows = [], None, []
    for line in path.read_text().splitlines() + ["#"]:
        line = line.split("//")[0].strip()
        if not line:
            continue
        if line == "#":
            if header is not None:
                blocks.append((header, np.array(rows, dtype=float).reshape(len(rows), len(header))))
            header, rows = None, []
        elif header is None:
            header = line.split()
        else:
            rows.append([_num(v) for v in line.split()])
    return blocks


def eq3(e, pos, ref, tool, S):
    """docs/table-format.md, "What the table means", written out (um, urad, mm)."""
    x, y, z = ((pos - np.asarray(ref)) * 1e-3).T
    tx, ty, tz = np.asarray(tool) * 1e-3
    sxy, sxz, syz = S
    E = lambda a, t: e[a][t]  # noqa: E731
    dX = (-E("X", "dx") - E("Y", "dx") + E("Z", "dx") - y * (E("X", "ez") + E("Y", "ez"))
          - z * (E("X", "ey") + E("Y", "ey")) + y * sxy - z * sxz
          + ty * (E("X", "ez") + E("Y", "ez") - E("Z", "ez"))
          + tz * (E("Z", "ey") - E("X", "ey") - E("Y", "ey")))
    dY = (-E("X", "dy") - E("Y", "dy") + E("Z", "dy") + x * E("X", "ez")
          + z * (E("X", "ex") + E("Y", "ex")) - z * syz
          + tx * (E("Z", "ez") - E("X", "ez") - E("Y", "ez"))
          + tz * (E("X", "ex") + E("Y", "ex") - E("Z", "ex")))
    dZ = (-E("X", "dz") - E("Y", "dz") + E("Z", "dz") - x * E("X", "ey")
          + y * (E("X", "ex") + E("Y", "ex"))
          + tx * (E("X", "ey") + E("Y", "ey") - E("Z", "ey"))
          + ty * (E("Z", "ex") - E("X", "ex") - E("Y", "ex")))
    return np.column_stack([dX, dY, dZ])


def read_isg(out: Path, tool=(0.0, 0.0, 0.0)):
    lis = {}
    for line in (out / "volcomp.lis").read_text().splitlines():
        line = line.split("#")[0].strip()
        if line:
            k, v = line.split(None, 1)
            lis[k] = v.strip()
    if lis.get("file_format[0]") != "ISG_CSV" or lis.get("interpolation") != "GRID":
        raise FormatError("expected an ISG_CSV file with GRID interpolation")
    blocks = read_isg_blocks(out / lis["file[0]"])
    if any(h[:3] == ["X", "Y", "Z"] for h, _ in blocks):  # the 3D map layout
        h, d = next(b for b in blocks if b[0][:3] == ["X", "Y", "Z"])
        ks = [np.unique(d[:, i]) for i in range(3)]
        shape = tuple(k.size for k in ks)
        if shape[0] * shape[1] * shape[2] != d.shape[0]:
            raise FormatError("not a full grid")
        order = np.lexsort((d[:, 2], d[:, 1], d[:, 0]))
        grid = d[order][:, 3:6].reshape(*shape, 3) * 1e3
        from scipy.interpolate import RegularGridInterpolator
        f = [RegularGridInterpolator(ks, grid[..., c]) for c in range(3)]

        def corr(pos, state):
            p = np.column_stack([np.clip(pos[:, i], ks[i][0], ks[i][-1]) for i in range(3)])
            return -np.column_stack([g(p) for g in f])
        return corr
    terms = {"X": "dx", "Y": "dy", "Z": "dz", "A": "ex", "B": "ey", "C": "ez"}
    comp: dict[str, tuple[np.ndarray, dict[str, np.ndarray]]] = {}
    S = [0.0, 0.0, 0.0]
    for header, d in blocks:
        if header[0] in AX and len(header) > 1:
            a = header[0]
            cols = {}
            for i, name in enumerate(header[1:], start=1):
                assert name[0] == "E" and name[2] == a, name
                t = terms[name[1]]
                cols[t] = d[:, i] * (1e3 if t.startswith("d") else 1e6)
            comp[a] = (d[:, 0], cols)
        else:
            for i, name in enumerate(header):
                v = d[0, i] * 1e6
                if name == "C0Y":
                    S[0] = v
                elif name == "B0Z":
                    S[1] = -v
                elif name == "A0Z":
                    S[2] = v

    def corr(pos, state):
        e = {a: {t: hold_interp(pos[:, AX.index(a)], comp[a][0], comp[a][1].get(
            t, np.zeros(comp[a][0].size))) for t in ("dx", "dy", "dz", "ex", "ey", "ez")}
            for a in AX}
        return -eq3(e, pos, (0.0, 0.0, 0.0), tool, S)
    return corr


# --- LinuxCNC trt-kins (five-axis) ---------------------------------------------------------

def read_linuxcnc_trt(out: Path):
    """trt-kins.hal (``setp COMP.PIN VALUE``) and trt-kins.ini (``[JOINT_n]`` /
    ``HOME_OFFSET = deg``) as halcmd and the INI reader take them. Returns (component,
    pins {pin: mm}, home {joint: deg}). Comment lines (#) and blank lines are skipped;
    anything else is a FormatError."""
    comp, pins = None, {}
    for line in (out / "trt-kins.hal").read_text().splitlines():
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        m = re.fullmatch(r"setp ([A-Za-z0-9_-]+)\.([a-z-]+) (\S+)", line)
        if not m:
            raise FormatError(f"not a setp line: {line!r}")
        if comp not in (None, m[1]):
            raise FormatError("two components")
        comp = m[1]
        if m[2] in pins:
            raise FormatError(f"{m[2]} set twice")
        pins[m[2]] = _num(m[3])
    home, joint = {}, None
    for line in (out / "trt-kins.ini").read_text().splitlines():
        t = line.strip()
        if not t or t.startswith("#"):
            continue
        m = re.fullmatch(r"\[JOINT_(\d+)\]", t)
        if m:
            joint = int(m[1])
            continue
        k, eq, v = t.partition("=")
        if joint is None or not eq or k.strip() != "HOME_OFFSET" or joint in home:
            raise FormatError(f"unexpected INI line {line!r}")
        home[joint] = _num(v.strip())
    return comp, pins, home


def trt_joints(kind: str, pins: dict, work_mm, angles_deg):
    """trtfuncs.c's inverse kinematics (tool-offset 0): joints = r + o + R_tilt (Rz(c) (w - r)
    - o), written with rotation matrices. angles (N, 2): tilt, C in degrees."""
    w = np.asarray(work_mm, float).reshape(-1, 3)
    ang = np.radians(np.asarray(angles_deg, float).reshape(-1, 2))
    r = np.array([pins["x-rot-point"], pins["y-rot-point"], pins["z-rot-point"]])
    if kind == "xyzac-trt":
        o = np.array([0.0, pins["y-offset"], pins["z-offset"]])
    else:
        o = np.array([pins["x-offset"], 0.0, pins["z-offset"]])
    out = np.empty_like(w)
    for i, ((t, c), p) in enumerate(zip(ang, w)):
        ct, st, cc, sc = np.cos(t), np.sin(t), np.cos(c), np.sin(c)
        rz = np.array([[cc, -sc, 0.0], [sc, cc, 0.0], [0.0, 0.0, 1.0]])
        tilt = (np.array([[1.0, 0.0, 0.0], [0.0, ct, -st], [0.0, st, ct]]) if kind == "xyzac-trt"
                else np.array([[ct, 0.0, st], [0.0, 1.0, 0.0], [-st, 0.0, ct]]))
        out[i] = r + o + tilt @ (rz @ (p - r) - o)
    return out


# --- grblHAL rtcp_ac (five-axis) ------------------------------------------------------------

def read_grblhal_rtcp(out: Path):
    """rtcp_ac.nc: ``$640=..`` .. ``$645=..`` (a_vector x y z, c_vector x y z, mm) as a
    grblHAL sender sends them; ``;`` lines are comments. Returns (a, c) arrays."""
    vals = {}
    for line in (out / "rtcp_ac.nc").read_text().splitlines():
        t = line.strip()
        if not t or t.startswith(";"):
            continue
        m = re.fullmatch(r"\$(\d+)=(-?\d+\.\d{3})", t)
        if not m or int(m[1]) in vals:
            raise FormatError(f"not a setting line: {line!r}")
        vals[int(m[1])] = _num(m[2])
    if sorted(vals) != list(range(640, 646)):
        raise FormatError(f"settings {sorted(vals)}")
    return np.array([vals[640], vals[641], vals[642]]), np.array([vals[643], vals[644], vals[645]])


def rtcp_joints(a, c, work_mm, angles_deg):
    """rtcp_ac.c's rtcp_forward in float32 as the controller computes (its settings and
    arithmetic are float): q = a + Rx(A) (c + Rz(C) p), p = w - (a + c) (the RTCP origin
    at the C centre). angles (N, 2): A, C degrees."""
    f = np.float32
    a, c = np.asarray(a, f), np.asarray(c, f)
    out = []
    for p, (A, C) in zip(np.asarray(work_mm, f) - (a + c), np.radians(angles_deg).astype(f)):
        ca, sa, cc, sc = np.cos(A), np.sin(A), np.cos(C), np.sin(C)
        rz = np.array([[cc, -sc, 0], [sc, cc, 0], [0, 0, 1]], f)
        rx = np.array([[1, 0, 0], [0, ca, -sa], [0, sa, ca]], f)
        out.append(a + rx @ (c + rz @ p))
    return np.array(out, dtype=float)


# --- Siemens SINUMERIK toolholder data $TC_CARR (five-axis) -------------------------------

#: REAL parameters of a data set the reader takes (W1: l1 1..3, l2 4..6, v1 7..9, v2 10..12,
#: angles 13/14, l3 15..17, l4 18..20, offsets 24/25); 21/22 AXIS, 23 CHAR.
CARR_REAL = set(range(1, 21)) | {24, 25}


def read_sinumerik_carr(path: Path):
    """A part program of $TC_CARR assignments as the control runs it: the header
    ``%_N_NAME_MPF``, ``;`` comments, blocks ``N<k> $TC_CARR<i>[<m>]=<value>`` (with an
    optional ``; comment``) and a last block ``M30``. One data set m. Parameters not
    assigned keep their preset (W1: 0, type "T"). Returns (m, {i: value}) with REAL values
    as float, 21/22 as axis names, 23 as the upper-case type letter."""
    lines = path.read_text().splitlines()
    if not lines or not re.fullmatch(r"%_N_[A-Z][A-Z0-9_]*_MPF", lines[0]):
        raise FormatError(f"no program header: {lines[:1]}")
    vals: dict[int, object] = {}
    carrier, ended, last_n = None, False, 0
    for line in lines[1:]:
        t = line.split(";", 1)[0].strip()
        if not t:
            continue
        if ended:
            raise FormatError(f"block after M30: {line!r}")
        m = re.fullmatch(r"N(\d+) (.*)", t)
        if not m or int(m[1]) <= last_n:
            raise FormatError(f"not an ascending block number: {line!r}")
        last_n, body = int(m[1]), m[2]
        if body == "M30":
            ended = True
            continue
        m = re.fullmatch(r"\$TC_CARR(\d+)\[(\d+)\]=(\S+)", body)
        if not m:
            raise FormatError(f"not a $TC_CARR assignment: {line!r}")
        i, k, v = int(m[1]), int(m[2]), m[3]
        if carrier not in (None, k):
            raise FormatError("two data sets")
        carrier = k
        if i in vals:
            raise FormatError(f"$TC_CARR{i} assigned twice")
        if i in CARR_REAL:
            if not re.fullmatch(r"-?\d+(\.\d+)?", v):
                raise FormatError(f"$TC_CARR{i}: not a REAL: {v!r}")
            vals[i] = _num(v)
        elif i in (21, 22):
            if not re.fullmatch(r"[A-Z][A-Z0-9_]*", v):
                raise FormatError(f"$TC_CARR{i}: not an axis name: {v!r}")
            vals[i] = v
        elif i == 23:
            m = re.fullmatch(r'"([TPMtpm])"', v)
            if not m:
                raise FormatError(f"$TC_CARR23: kinematic type T, P or M expected: {v!r}")
            vals[i] = m[1].upper()
        else:
            raise FormatError(f"$TC_CARR{i} is not a geometry parameter")
    if not ended:
        raise FormatError("no M30")
    for i in CARR_REAL:
        vals.setdefault(i, 0.0)
    vals.setdefault(23, "T")
    return carrier, vals


def _turn(v, k, a):
    """v turned right-handed by a (rad) about the unit vector k (Rodrigues' formula)."""
    return v * np.cos(a) + np.cross(k, v) * np.sin(a) + k * np.dot(k, v) * (1.0 - np.cos(a))


def carr_joints(vals: dict, work_mm, angles_deg):
    """Kinematic type P (the part turns; rotary axis 2 is carried by rotary axis 1; the
    offset vectors refer to the non-swivelled state): the machine position of a workpiece
    point w is l2 + R1 (l3 + R2 (l4 + w)), R turning the part right-handed about the
    (normalised) rotary axis vector by the axis position minus its offset ($TC_CARR24/25).
    angles (N, 2): the part's rotations (deg) the program asks for; returns (positions mm,
    axis positions deg) -- the axis goes to the rotation plus its offset."""
    if vals[23] != "P":
        raise FormatError(f"kinematic type {vals[23]}, not P")
    vec = {name: np.array([vals[i] for i in (a, a + 1, a + 2)])
           for name, a in (("l2", 4), ("v1", 7), ("v2", 10), ("l3", 15), ("l4", 18))}
    for k in ("v1", "v2"):
        n = np.linalg.norm(vec[k])
        if n == 0.0:
            raise FormatError(f"rotary axis vector {k} is 0")
        vec[k] = vec[k] / n
    off = np.array([vals[24], vals[25]])
    rot = np.radians(np.asarray(angles_deg, float).reshape(-1, 2))
    out = np.array([vec["l2"] + _turn(vec["l3"] + _turn(vec["l4"] + w, vec["v2"], a2),
                                      vec["v1"], a1)
                    for w, (a1, a2) in zip(np.asarray(work_mm, float).reshape(-1, 3), rot)])
    return out, np.asarray(angles_deg, float).reshape(-1, 2) + off[None, :]


# --- ISG / Beckhoff universal kinematics ID 91 (five-axis) --------------------------------

def read_isg_kin91(path: Path):
    """A channel parameter list fragment (TF5240, V3.00 syntax): ``# comments`` and lines
    ``trafo[j].axis[k].type|orientation[i]|point[i] VALUE``, one transformation j.
    Returns {k: {"type": int, "orientation": (3,), "point": (3,) mm}} (point read in
    0.1 um)."""
    axes: dict[int, dict] = {}
    trafo = None
    for line in path.read_text().splitlines():
        t = line.strip()
        if not t or t.startswith("#"):
            continue
        m = re.fullmatch(r"trafo\[(\d)\]\.axis\[(\d)\]\.(type|orientation|point)"
                         r"(?:\[(\d)\])? +(-?\d+(?:\.\d+)?)", t)
        if not m:
            raise FormatError(f"not a universal kinematics axis entry: {line!r}")
        if trafo not in (None, m[1]):
            raise FormatError("two transformations")
        trafo = m[1]
        ax = axes.setdefault(int(m[2]), {})
        key = m[3] if m[4] is None else f"{m[3]}[{m[4]}]"
        if key in ax or (m[3] == "type") != (m[4] is None) or (m[4] is not None and int(m[4]) > 2):
            raise FormatError(f"bad or repeated entry: {line!r}")
        ax[key] = _num(m[5])
    out = {}
    for k, ax in axes.items():
        want = {"type"} | {f"{n}[{i}]" for n in ("orientation", "point") for i in range(3)}
        if set(ax) != want or ax["type"] != 2:
            raise FormatError(f"axis[{k}]: a rotary axis needs type 2, orientation and point")
        o = np.array([ax[f"orientation[{i}]"] for i in range(3)])
        if not np.any(o):
            raise FormatError(f"axis[{k}]: zero orientation vector")
        out[k] = {"type": 2, "orientation": o / np.linalg.norm(o),
                  "point": np.array([ax[f"point[{i}]"] for i in range(3)]) * 1e-4}
    return out


def _line_rotation(point, direction, angle_rad):
    """4x4: rotation by angle (right-handed) about the line through point along direction."""
    k = np.asarray(direction, float)
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    R = np.eye(3) + np.sin(angle_rad) * K + (1.0 - np.cos(angle_rad)) * (K @ K)
    H = np.eye(4)
    H[:3, :3] = R
    H[:3, 3] = point - R @ point
    return H


def kin91_joints(axes: dict, chain: tuple[int, int], work_mm, angles_deg):
    """The universal kinematics with RTCP: the chain runs from the workpiece over the
    workpiece-side axes ``chain`` (C first, then the tilt: axis indices) to the linear axes
    and the tool (zero position at the origin, linear axes along x, y, z). The tool tip's
    position in the workpiece is H_C(c) H_tilt(a) q, each H a rotation about the axis'
    point and orientation by its angle; the linear axes go to q = (H_C H_tilt)^-1 w.
    angles (N, 2) = (tilt, C) deg, also the axis angles (RTCP)."""
    c_axis, tilt_axis = (axes[k] for k in chain)
    out = []
    for w, (a, c) in zip(np.asarray(work_mm, float).reshape(-1, 3),
                         np.radians(np.asarray(angles_deg, float).reshape(-1, 2))):
        H = (_line_rotation(c_axis["point"], c_axis["orientation"], c)
             @ _line_rotation(tilt_axis["point"], tilt_axis["orientation"], a))
        out.append((np.linalg.inv(H) @ np.append(w, 1.0))[:3])
    return np.array(out), np.asarray(angles_deg, float).reshape(-1, 2)


READERS = {
    "linuxcnc-comp": lambda out: read_linuxcnc_comp(out)[0],
    "linuxcnc-matrixkins": read_matrixkins,
    "klipper-skew": read_klipper,
    "marlin": read_marlin,
    "rrf-m556": read_rrf_m556,
    "klipper-twist": read_klipper_twist,
    "sinumerik-lec": read_sinumerik_lec,
    "sinumerik-cec": lambda out: read_sinumerik_cec(out)[0],
    "heidenhain-com": read_heidenhain,
    "fanuc-pitch": read_fanuc,
    "isg-csv": read_isg,
}
