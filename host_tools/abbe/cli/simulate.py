"""``abbe simulate SPEC.toml -o DIR``: a simulated measurement campaign and its ground truth."""

from __future__ import annotations

import argparse
import json

from abbe.cli.conventions import examples, json_file, json_option, json_to_stdout, print_json


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "simulate", help="simulate a three-axis machine and its measurement campaign from a "
                         "spec",
        description="Simulate a virtual three-axis machine (exact nonlinear kinematics, 21 "
                    "geometric errors, optional effects) and write a complete campaign: "
                    "DIR/machine.toml, the 6D laser CSVs, the ballbar CSVs and the ground "
                    "truth DIR/truth/truth.json (+ DIR/truth/true_table.json). "
                    "Spec format: docs/formats.md, 'Ballbar and simulation'.",
        epilog=examples("abbe simulate examples/vmc500/spec.toml -o sim-out"))
    p.add_argument("spec", help="simulation spec (TOML)")
    p.add_argument("-o", "--out", required=True, help="output directory (created if needed)")
    json_option(p, "a summary (the files written, the linearisation check)")
    p.set_defaults(func=run)


def linearisation_check(spec, n: int = 4000) -> float:
    """Max |exact chain - Eq. 3 on the true table| (um) over random workspace points."""
    import numpy as np

    from abbe.model.reference import spatial_error
    from abbe.model.table import AXES
    from abbe.sim.truth import truth_table
    from abbe.sim.virtual_machine import VirtualMachine

    truth = spec.truth()
    vm = VirtualMachine(truth)
    rng = np.random.default_rng(spec.seed)
    lo = np.array([spec.travel_mm[a][0] for a in AXES])
    hi = np.array([spec.travel_mm[a][1] for a in AXES])
    pos = lo + (hi - lo) * rng.random((n, 3))
    ds = rng.choice([-1.0, 1.0], size=(n, 3))
    exact = vm.tool_error_um(pos, ds)
    lin = spatial_error(truth_table(truth, include=("squareness", "cyclic", "backlash",
                                                    "tool_offset")), pos, ds)
    return float(np.max(np.abs(exact - lin)))


def run(args: argparse.Namespace) -> int:
    # imported here: the simulator pulls in scipy, which every other command would pay for
    from abbe.sim.campaign import simulate_campaign, write_campaign
    from abbe.sim.spec import load_spec

    from abbe.formats.output import Outputs

    with Outputs() as outs:
        outs.directory(args.out, option="--out")  # checked before the work
        js = outs.file(json_file(args), option="--json") if json_file(args) else None
        spec = load_spec(args.spec)
        files = simulate_campaign(spec)
        written = write_campaign(files, args.out, outs)
        lin = linearisation_check(spec)
        doc = {"out": args.out, "files": sorted(files), "linearisation_max_um": lin}
        if js is not None:
            js.write_text(json.dumps(doc, indent=2, allow_nan=False) + "\n", encoding="utf-8")
    if json_to_stdout(args):
        print_json(doc)
    else:
        print(f"abbe simulate: {spec.name} (seed {spec.seed}): wrote {len(written)} files to "
              f"{args.out}")
        for rel in sorted(files):
            print(f"  {rel}")
        print(f"  exact kinematics vs linearised Eq. 3: max difference {lin:.2e} um")
    return 0
