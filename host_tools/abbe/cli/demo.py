"""``abbe demo``: the whole pipeline on the bundled example machine (README's main job)."""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import sys
from pathlib import Path

from abbe.cli.conventions import examples, json_file, json_option, json_to_stdout, print_json


def _default_example() -> Path:
    from abbe.paths import examples_dir
    return examples_dir() / "vmc500"


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "demo", help="run fit -> tables -> predict -> diagnose -> compensate on the three-axis "
                     "example (--five-axis: identify the trunnion example)",
        description="The demo pipeline on a bundled example machine (default: the vmc500 example "
                    "shipped with abbe): fit, tables, build check, ballbar prediction, diagnosis, "
                    "compensation in the loop, and an HTML report in OUT/index.html.",
        epilog=examples("abbe demo", "abbe demo -o abbe-demo --json abbe-demo/summary.json"))
    p.add_argument("--example", type=Path, default=None, help="example machine directory")
    p.add_argument("-o", "--out", type=Path, default=Path("abbe-demo"),
                   help="output directory (default: ./abbe-demo)")
    json_option(p, "the summary figures")
    p.add_argument("--no-diagnose", action="store_true", help="skip the diagnose step")
    p.add_argument("--five-axis", action="store_true",
                   help="the five-axis demo instead: identify the trunnion5ax_complete example "
                        "(A/C trunnion, probing + R-test + indexer + a datum sphere at a second "
                        "height) and compare with its truth")
    p.set_defaults(func=run)


def _unstage(staging: Path, final: Path) -> None:
    """The demo ran in ``staging``: name ``final`` instead in the files that record paths."""
    old, new = str(staging), str(final)
    for p in staging.rglob("*"):
        if p.suffix in (".json", ".txt", ".html") and p.is_file():
            text = p.read_text(encoding="utf-8")
            if old in text:
                p.write_text(text.replace(old, new), encoding="utf-8")


class _FinalPaths(io.TextIOBase):
    """A stdout that names the final output folder where the demo's steps print the
    staging folder they work in (the user finds OUT, never ``.OUT.abbe-tmp-...``)."""

    def __init__(self, target: io.TextIOBase, staging: Path, final: str) -> None:
        self._target = target
        # the forms a step may print: as given, absolute, resolved
        forms = {str(staging), str(staging.absolute()), str(staging.resolve())}
        self._subs = sorted(((f, final) for f in forms), key=lambda fs: -len(fs[0]))
        self._pending = ""

    def writable(self) -> bool:
        return True

    def write(self, s: str) -> int:
        # whole lines only, so that a path split over two write() calls is still found
        self._pending += s
        *lines, self._pending = self._pending.split("\n")
        for ln in lines:
            self._target.write(self._fix(ln) + "\n")
        return len(s)

    def _fix(self, text: str) -> str:
        for old, new in self._subs:
            text = text.replace(old, new)
        return text

    def flush(self) -> None:
        if self._pending:
            self._target.write(self._fix(self._pending))
            self._pending = ""
        self._target.flush()


def run(args: argparse.Namespace) -> int:
    from abbe.cli.demo_pipeline import run_demo
    from abbe.formats.output import Outputs

    if args.five_axis:
        return _run_five_axis(args)
    from abbe.model import clib
    try:  # said once, before any step: the demo predicts and compensates through the library
        clib.load_library()
    except clib.LibraryNotFound as exc:
        print(f"abbe demo: error: the demo runs the C library (prediction, compensation in "
              f"the loop): {exc.what}; build it with 'cmake -S . -B build && cmake --build "
              "build' in the repository root, or point ABBE_LIB at libabbe.so",
              file=sys.stderr)
        return 3
    example = args.example or _default_example()
    with Outputs() as outs:
        staging = outs.directory(args.out, option="--out")
        js = outs.file(json_file(args), option="--json") if json_file(args) else None
        # with --json - the steps' progress goes to stderr: stdout holds the JSON alone
        out = _FinalPaths(sys.stderr if json_to_stdout(args) else sys.stdout, staging,
                          str(args.out))
        try:
            with contextlib.redirect_stdout(out):
                res = run_demo(example, staging, diagnose=not args.no_diagnose)
        finally:
            out.flush()
        _unstage(staging, Path(args.out).resolve())
        if js is not None:
            js.write_text(json.dumps(res.summary, indent=2, default=str, allow_nan=False))
    s = res.summary
    if json_to_stdout(args):
        print(json.dumps(s, indent=2, default=str, allow_nan=False))
        return 0
    print(f"abbe demo ({s['machine']}, {s['ballbar']}): prediction max residual "
          f"{s['prediction_max_residual_laser_only_um']} um (laser-only) -> {s['prediction_max_residual_um']} um; "
          f"roundness {s['roundness_before_um']} +- {s['roundness_before_U_um']} -> "
          f"{s['roundness_after_um']} +- {s['roundness_after_U_um']} um (U, k = 2) "
          f"({s['improvement_pct']} % better, model-ideal {s['ideal_improvement_pct']} %)")
    return 0


def _run_five_axis(args: argparse.Namespace) -> int:
    from abbe.cli.fit_five_axis import demo_five_axis
    from abbe.formats.output import Outputs
    from abbe.paths import examples_dir

    example = args.example or examples_dir() / "trunnion5ax_complete"
    with Outputs() as outs:
        staging = outs.directory(args.out, option="--out")
        js = outs.file(json_file(args), option="--json") if json_file(args) else None
        with contextlib.redirect_stdout(sys.stderr if json_to_stdout(args) else sys.stdout):
            s = demo_five_axis(Path(example), staging)
        _unstage(staging, Path(args.out).resolve())
        if js is not None:
            js.write_text(json.dumps(s, indent=2, allow_nan=False))
    if json_to_stdout(args):
        print_json(s)
        return 0
    print(f"abbe demo --five-axis ({s['machine']}, {s['kinematics']}): "
          f"{s['within_interval_or_1um_5urad']} of {s['observable_location_errors']} observable "
          f"location errors within their interval of the truth; not observable (named): "
          f"{', '.join(s['unobservable']) or 'none'}; sphere-centre dispersion {s['dispersion_before_um']:.2f}"
          f" -> {s['dispersion_after_um']:.2f} um (held out {s['heldout_before_um']:.2f} -> "
          f"{s['heldout_after_um']:.2f} um); report in {args.out}/report/index.html")
    return 0
