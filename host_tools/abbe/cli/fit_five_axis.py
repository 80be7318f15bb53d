"""``abbe fit`` for a five-axis machine file (one with a ``[rotary]`` section).

Reads the plan's probing / R-test / indexer files, identifies the location
errors (and the error motions the plan resolves, ``[rotary.fit] harmonics``)
and writes OUT/five_axis.json (the identified table, observability,
dispersion, held-out judgement), OUT/model_five.bin (the identified model as a
format 1.2 five-axis table for the C library, :mod:`abbe.formats.five_axis_blob`:
the solution in the fit's convention, :func:`table_solution`; its dispersion on the
probed centres is re-predicted through the C library and reported),
OUT/report.txt and OUT/report/ (HTML with polar plots), atomically
(:class:`abbe.formats.output.Outputs`).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from abbe.formats.output import Outputs


def is_five_axis(path: str) -> bool:
    """True when the machine file has a ``[rotary]`` section (bad files raise AbbeInputError)."""
    from abbe.formats.machine import load_machine
    return load_machine(path).five_axis is not None


def identify_into(machine_path: str | Path, staging: Path, report: bool = True,
                  mc_draws: int = 0):
    """Identify a five-axis machine file and write five_axis.json, report.txt and report/
    into ``staging``; ``mc_draws`` > 0 runs the Monte Carlo check of U (GUM S1) and states
    its U where the first order is more than 10 % off; returns (spec, result, json
    document, text, timings s)."""
    from abbe.analysis.five_axis.data import load_plan
    from abbe.analysis.five_axis.identify import identify
    from abbe.analysis.five_axis.problem import build_params
    from abbe.analysis.five_axis.report import text_report, to_json, write_html
    from abbe.formats.machine import load_machine

    t0 = time.perf_counter()
    machine = load_machine(machine_path)
    spec = machine.five_axis
    plan = load_plan(spec)
    t_read = time.perf_counter()
    params = build_params(spec, plan.blocks)
    res = identify(spec, plan.blocks, params)
    t_fit = time.perf_counter()
    doc = to_json(res, spec, plan)
    if mc_draws:
        from abbe.analysis.five_axis.uncertainty import monte_carlo, state_monte_carlo
        state_monte_carlo(doc, monte_carlo(spec, plan.blocks, params, res, draws=mc_draws))
    doc["machine"] = machine.name
    doc["provenance"] = {"machine_file": str(machine.path), "sha256": machine.sha256}
    doc["blob"] = write_table(res, spec, Path(staging), plan.blocks)
    (Path(staging) / "five_axis.json").write_text(
        json.dumps(doc, indent=2, allow_nan=False) + "\n", encoding="utf-8")
    text = text_report(doc)
    (Path(staging) / "report.txt").write_text(text, encoding="utf-8")
    if report:
        write_html(res, doc, Path(staging) / "report")
    return spec, res, doc, text, {"read": t_read - t0, "fit": t_fit - t_read}


def write_table(res, spec, staging: Path, blocks=None) -> dict:
    """Write model_five.bin (format 1.2) into ``staging``: the solution in the fit's
    convention (:func:`table_solution`). Returns the JSON entry describing the file, with
    the convention and, given the plan's ``blocks``, the table's own dispersion on the
    probed centres re-predicted through the C library (``repredicted``)."""
    import zlib

    from abbe.analysis.five_axis.problem import errors_from
    from abbe.analysis.five_axis.table_check import repredict
    from abbe.formats.five_axis_blob import write_five_blob

    from abbe.model.table import TableError

    x, convention = table_solution(res)
    try:
        blob = write_five_blob(spec.geometry, errors_from(res.params, x, res.harmonics))
    except TableError as exc:
        # a weak plan's convention can hold values beyond the table's encoding (an angle
        # beyond 3906 urad): then only what the plan observes is written, as before issue 33
        import numpy as np

        x = np.where(np.isfinite(res.x), res.x, 0.0)
        blob = write_five_blob(spec.geometry, errors_from(res.params, x, res.harmonics))
        machine = [i for i, p in enumerate(res.params) if p.kind != "setup"]
        convention = {
            "fixed_at_zero": [res.params[i].name for i in machine if not res.obs.observable[i]],
            "determined_in_convention": {}, "smallest_of_undetermined": [],
            "uncertain_in_convention": [],
            "statement": (f"the fit's convention holds values the table cannot encode ({exc}): "
                          "only the errors this plan observes are written, every other one "
                          "as 0 (not compensated); a richer plan (more spheres, heights, "
                          "angles) determines them"),
            "workpiece_datum": convention["workpiece_datum"]}
    (staging / "model_five.bin").write_bytes(blob)
    entry = {"file": "model_five.bin", "format": "1.2", "bytes": len(blob),
             "crc32": f"0x{zlib.crc32(blob[:-4]) & 0xFFFFFFFF:08X}",
             "written_as_zero_not_observable": convention["fixed_at_zero"],
             "convention": convention}
    if blocks is not None:
        entry["repredicted"] = repredict(spec.geometry, blocks, blob)
    return entry


def table_solution(res) -> tuple:
    """The machine errors the table holds and the convention they hold them in.

    The plan cannot see some combinations of errors (the angular zeros: EA0A / EB0B and
    EC0C). The fit fixes a set of them at 0 (``res.obs.fixed``, its convention) and then
    determines every other error *in that convention*: e.g. the C line's position and
    tilt relative to the tilt axis (EY0C, EA0C on A/C; EX0C, EB0C on B/C), which alone
    are not observable because a zero offset of the tilt axis moves them. The table holds
    that solution whole: leaving those values out would leave half of the tool tip's
    error uncompensated (issue 33). What the convention leaves out is a rigid placement of
    the workpiece, which a workpiece datum (probing the part) absorbs.

    Returns (parameter vector, convention dict for five_axis.json)."""
    import numpy as np

    x = np.array(res.x_table if res.x_table is not None else np.nan_to_num(res.x),
                 dtype=np.float64)
    machine = [i for i, p in enumerate(res.params) if p.kind != "setup"]
    zero = [res.params[i].name for i in machine if x[i] == 0.0 and not res.obs.observable[i]]
    held = {res.params[i].name: float(x[i]) for i in machine
            if not res.obs.observable[i] and x[i] != 0.0}
    smallest = [res.params[i].name for i in res.min_norm]
    # held values the campaign determines only to worse than their typical size, even in
    # the convention (one sphere height with error motions): named, the plan to blame
    sdc = res.sd_convention
    uncertain = [res.params[i].name for i in machine if not res.obs.observable[i]
                 and sdc is not None and np.isfinite(sdc[i])
                 and 1.96 * sdc[i] > res.params[i].scale]
    # a plan with a datum that leaves nothing unobserved has no convention to state
    complete = bool(res.obs.observable.all()) and any(b.kind == "datum" for b in res.blocks)
    return x, {
        "fixed_at_zero": zero,
        "determined_in_convention": held,
        "smallest_of_undetermined": smallest,
        "prior_one_typical_size": bool(res.prior),
        "uncertain_in_convention": uncertain,
        "statement": ("the plan observes every error it fits: the table holds the fit's "
                      "values, no convention" if complete else
                      "the errors this plan cannot observe alone are held in the fit's "
                      "convention: " + (", ".join(zero) or "nothing") + " fixed at 0, "
                      + (", ".join(held) or "nothing else") + " as the fit determined them "
                      "in that convention (only their combination with the fixed ones is "
                      "seen)" + (", each with a prior of one typical size (10 um / 20 urad "
                                 "for a location error, 1 um / 5 urad for a motion "
                                 "coefficient) that holds the smallest values the campaign "
                                 "allows where it leaves them noise" if res.prior else "")
                      + "; the table reproduces the campaign in this convention"
                      + ("; of what the plan leaves undetermined even then (" + ", ".join(smallest)
                         + "), the smallest errors consistent with the campaign are held: a "
                         "richer plan (spheres at other radii and heights) would determine "
                         "them" if smallest else "")
                      + ("; UNCERTAIN: " + ", ".join(uncertain) + " are held with a 95 % "
                         "interval wider than their typical size even in the convention: "
                         "this table may compensate poorly away from the probed poses; "
                         "probe spheres at several heights and radii" if uncertain else "")),
        "workpiece_datum": (
            "the plan observes every error: the table frame is its datum's ("
            + ", ".join(f"{b.key}, declared to {float(b.sigma):g} um" for b in res.blocks
                        if b.kind == "datum") + "); a workpiece is placed in that frame by "
            "probing it after clamping" if complete else
            "what the plan cannot see is a rigid placement of the workpiece on the table (its "
            "position and orientation): a workpiece datum, i.e. probing the part after "
            "clamping it, absorbs it"),
    }


def run_five_axis(args: argparse.Namespace) -> int:
    t0 = time.perf_counter()
    outs = Outputs()
    try:
        staging = outs.directory(args.out, option="--out")
        spec, res, _doc, text, times = identify_into(args.machine, staging, not args.no_report,
                                                     mc_draws=args.mc)
    except BaseException:
        outs.abort()
        raise
    outs.commit()
    if not args.quiet:
        print(text, end="")
    print(f"abbe fit: wrote {args.out} (five-axis {spec.geometry.kind}: rank "
          f"{res.obs.rank} of {res.obs.n_params}, {int(res.obs.observable.sum())} observable)")
    if args.bench:
        print(f"bench: read+sphere fits {1000 * times['read']:8.1f} ms")
        print(f"bench: identification   {1000 * times['fit']:8.1f} ms")
        print(f"bench: total            {1000 * (time.perf_counter() - t0):8.1f} ms")
    return 0


def demo_five_axis(example: Path, staging: Path) -> dict:
    """``abbe demo --five-axis``: identify the example and compare with its truth (kept in
    ``example/truth/truth.json``, apart from the data). Writes truth_comparison.txt."""
    _spec, _res, doc, _text, _t = identify_into(example / "machine.toml", staging)
    truth = json.loads((example / "truth" / "truth.json").read_text(encoding="utf-8"))
    lines = ["error        identified (95 %)          truth     within"]
    n = n_in = 0
    for r in doc["parameters"]:
        if r["kind"] != "location":
            continue
        tv = truth["location"].get(r["name"], 0.0)
        if not r["observable"]:
            lines.append(f"{r['name']:<12} not observable            {tv:10.3f}  (named)")
            continue
        ok = abs(r["value"] - tv) <= max(r["ci95"], 1.0 if r["unit"] == "um" else 5.0)
        n, n_in = n + 1, n_in + ok
        lines.append(f"{r['name']:<12} {r['value']:10.3f} +- {r['ci95']:7.3f} {r['unit']:<4} "
                     f"{tv:10.3f}  {'yes' if ok else 'NO'}")
    (Path(staging) / "truth_comparison.txt").write_text("\n".join(lines) + "\n", encoding="utf-8")
    d = doc["dispersion_um"]
    return {"machine": example.name, "kinematics": doc["kinematics"],
            "observable_location_errors": n, "within_interval_or_1um_5urad": n_in,
            "unobservable": [r["name"] for r in doc["parameters"]
                             if r["kind"] == "location" and not r["observable"]],
            "dispersion_before_um": d["before"], "dispersion_after_um": d["after"],
            "heldout_before_um": d["heldout_before"], "heldout_after_um": d["heldout_after"]}
