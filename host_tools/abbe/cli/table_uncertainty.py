"""``abbe table uncertainty``: the fitted table's predicted error and its expanded uncertainty
U (k = 2) at machine points and along each axis, from the coefficient covariances ``abbe
fit`` writes into model.json (docs/uncertainty.md, "Fitted table")."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np

from abbe.analysis.fit.uncertainty import K, point_u, terms_from_json
from abbe.cli.conventions import examples, json_file, json_option, json_to_stdout, list_option, print_json
from abbe.cli.options import in_range
from abbe.errors import AbbeInputError
from abbe.formats.limits import TABLE_JSON_MAX_BYTES
from abbe.formats.output import atomic_write
from abbe.formats.structured import JsonLocator, load_json
from abbe.formats.table_json import table_from_json
from abbe.model.reference import spatial_error, term_values
from abbe.model.table import AXES, LINEAR_TERMS

#: model.json's table block carries these beside the table JSON's own keys.
_TABLE_EXTRA = ("crc32", "size_bytes")


def _load(path: Path) -> tuple[Any, dict[str, Any], str]:
    p = path / "model.json" if path.is_dir() else path
    d, tf = load_json(p, what="fit model.json", max_bytes=4 * TABLE_JSON_MAX_BYTES)
    if not isinstance(d, dict) or d.get("format") != "abbe-fit":
        raise AbbeInputError("expected the model.json of a three-axis `abbe fit` (format "
                             "\"abbe-fit\"); a five-axis fit's five_axis.json states each "
                             "parameter's U itself",
                             file=tf.name, field="format")
    if "uncertainty" not in d:
        raise AbbeInputError("this model.json has no uncertainty block (an older abbe "
                             "wrote it): run `abbe fit` again",
                             file=tf.name, field="uncertainty")
    tab_d = d.get("table")
    if not isinstance(tab_d, dict):
        raise AbbeInputError("missing", file=tf.name, field="table")
    table = table_from_json({k: v for k, v in tab_d.items() if k not in _TABLE_EXTRA},
                            tf.name, JsonLocator(tf.text))
    return table, d, tf.name


def _cmd(args: argparse.Namespace) -> int:
    table, d, name = _load(args.model)
    terms = terms_from_json(d["uncertainty"], table, name)
    if len(args.pos) % 3:
        raise AbbeInputError(f"{len(args.pos)} numbers given; positions come in X Y Z triples",
                             field="pos_mm")
    out: dict[str, Any] = {"format": "abbe-table-uncertainty", "k": K, "model": str(args.model),
                           "method": d["uncertainty"].get("method"), "points": [], "along": {}}
    lines: list[str] = []
    if args.pos:
        pos = np.array(args.pos, dtype=float).reshape(-1, 3)
        val = spatial_error(table, pos)
        U = K * point_u(table, terms, pos)
        lines.append("pos_mm X Y Z | predicted dX dY dZ um | U (k = 2) dX dY dZ um")
        for p, v, u in zip(pos, val, U):
            lines.append(" ".join(f"{x:.4f}" for x in p) + " | " + " ".join(f"{x:.4f}" for x in v)
                         + " | " + " ".join(f"{x:.4f}" for x in u))
            out["points"].append({"pos_mm": p.tolist(), "error_um": v.tolist(), "U_um": u.tolist()})
    for a in args.along or ():
        if a not in terms:
            raise AbbeInputError(f"axis {a} has no fitted terms in this model.json "
                                 f"(fitted: {', '.join(terms) or 'none'})", field="--along")
        ax = table.axes[a]
        g = np.linspace(*ax.travel_mm, args.points)
        block: dict[str, Any] = {"pos_mm": g.tolist(), "terms": {}}
        lines.append(f"axis {a}: predicted term and U (k = 2) along the travel "
                     f"(um / urad; 0 at the reference point)")
        head = f"{a.lower()}_mm"
        cols = []
        for t, tu in terms[a].items():
            unit = "um" if t in LINEAR_TERMS else "urad"
            v = term_values(table, a, t, g)
            u = K * tu.u_at(ax, g)
            block["terms"][t] = {"unit": unit, "value": v.tolist(), "U": u.tolist()}
            head += f" | {t} U ({unit})"
            cols.append((v, u))
        lines.append(head)
        for i, x in enumerate(g):
            lines.append(f"{x:.3f}" + "".join(f" | {v[i]:.4f} {u[i]:.4f}" for v, u in cols))
        out["along"][a] = block
    if not args.pos and not args.along:
        raise AbbeInputError("give machine points (X Y Z ...) or --along AXIS", field="pos_mm")
    if json_to_stdout(args):
        print_json(out)
    else:
        print("\n".join(lines))
        if json_file(args):
            atomic_write(Path(str(json_file(args))),
                         (json.dumps(out, indent=1, allow_nan=False) + "\n").encode(),
                         option="--json")
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``abbe table uncertainty`` to the ``abbe table`` sub-commands."""
    q = sub.add_parser("uncertainty", help="predicted error and its U (k = 2) at machine points "
                       "and along each axis, from a fit's model.json",
                       description=__doc__.splitlines()[0],
                       epilog=examples("abbe table uncertainty fit-out/model.json 250 -200 -150",
                                       "abbe table uncertainty fit-out --along X Y --points 11"))
    q.add_argument("model", type=Path, help="the model.json of `abbe fit` (or its output folder)")
    q.add_argument("pos", nargs="*", type=in_range(-1e5, 1e5, "mm"), metavar="X Y Z",
                   help="machine positions, mm, in X Y Z triples")
    list_option(q, "--along", choices=AXES, metavar="AXIS",
                   help="tabulate every fitted term of AXIS and its U along the travel")
    q.add_argument("--points", type=int, default=11, choices=range(2, 1001), metavar="N",
                   help="positions along each axis for --along (2..1000, default 11)")
    json_option(q, "the results")
    q.set_defaults(func=_cmd)
