"""Entry points of ``abbe diagnose``: a machine file with its checks, or one positioning file.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from abbe.diagnose.blas import one_blas_thread
from abbe.diagnose.checks import Check
from abbe.diagnose.results import DiagnoseOptions, DiagnoseResult
from abbe.diagnose.selection import diagnose
from abbe.errors import AbbeInputError
from abbe.model.table import AXES, Table


def load_model(path: str | Any) -> Table:
    """A table from a blob (``model.bin``), a table JSON, or the ``model.json`` of
    ``abbe fit`` / ``abbe import`` (the one model reader, :mod:`abbe.formats.model_file`);
    AbbeInputError naming the file on any problem."""
    from abbe.formats.model_file import load_table
    if isinstance(path, Table):
        return path
    try:
        return load_table(path)
    except AbbeInputError as exc:
        raise exc.located(field="model") from None


def check_model_matches(table: Table, machine: Any, model_source: str = "model") -> None:
    """The model must belong to the machine file: same reference point (1 um), and every
    fitted travel inside the machine's travel (1 mm); else AbbeInputError."""
    ref_m = np.asarray(machine.reference_mm, dtype=np.float64)
    ref_t = np.asarray(table.reference_mm, dtype=np.float64)
    if np.max(np.abs(ref_m - ref_t)) > 1e-3:
        raise AbbeInputError(
            f"the model's reference point {tuple(round(v, 3) for v in ref_t)} mm differs from the "
            f"machine file's {tuple(round(v, 3) for v in ref_m)} mm: the model ({model_source}) "
            "and the measurements are for different machines", file=str(machine.path),
            line=machine.line_of("reference.point_mm"), field="reference.point_mm")
    for a, spec in machine.axes.items():
        lo, hi = table.axes[a].travel_mm
        mlo, mhi = spec.travel_mm
        if lo < mlo - 1.0 or hi > mhi + 1.0:
            raise AbbeInputError(
                f"the model covers {a} = [{lo:g}, {hi:g}] mm, outside the machine's travel "
                f"[{mlo:g}, {mhi:g}] mm: the model ({model_source}) belongs to another machine",
                file=str(machine.path), line=machine.line_of(f"axes.{a}.travel_mm"),
                field=f"axes.{a}.travel_mm")


@one_blas_thread
def diagnose_machine(machine: Any, model: Any, ballbar: list[str] | None = None,
                     laser: list[str] | None = None, options: DiagnoseOptions | None = None,
                     rezeroed: bool = False, mc_draws: int = 0) -> DiagnoseResult:
    """Diagnose the checks of a machine file against a model (the demo's entry point).

    ``machine``: path or :class:`abbe.formats.machine.Machine`; ``model``: path (blob / JSON) or
    Table; ``ballbar``: test names, ``laser``: axes (both None = every test in the file).
    """
    from abbe.diagnose.checks import ballbar_check, laser_check
    from abbe.formats.machine import load_machine
    m = machine if hasattr(machine, "ballbar") else load_machine(machine)
    table = load_model(model)
    check_model_matches(table, m, str(model) if not isinstance(model, Table) else "model")
    if ballbar is None and laser is None:
        ballbar, laser = sorted(m.ballbar), sorted(m.laser)
    checks: list[Check] = []
    for name in ballbar or []:
        checks.append(ballbar_check(m, name, table.reference_mm))
    for axis in laser or []:
        checks.append(laser_check(m, axis.upper(), table.reference_mm, rezeroed=rezeroed))
    if not checks:
        raise AbbeInputError("the machine file has no [ballbar.*] or [laser.*] test to check "
                             "the model with", file=str(m.path), field="ballbar")
    opts = options or DiagnoseOptions()
    sigma = getattr(m, "tool_offset_sigma_mm", None)
    if sigma is not None:
        # the machine file states how well it knows its tool: the declared quantity's prior
        opts = dataclasses.replace(opts, declared_tool_sigma_mm=float(sigma),
                                   declared_tool_stated=True)
    from abbe.diagnose.evidence import tool_is_declared
    from abbe.diagnose.table_uncertainty import table_covariance
    tcov = table_covariance(model, table)
    res = diagnose(table, checks, opts, table_cov=tcov)
    declared = tool_is_declared(table.tool_offset_mm, opts)
    res.declared = {"tool_offset_mm": [float(x) for x in table.tool_offset_mm],
                    "tool_offset_declared": declared,
                    "tool_offset_sigma_mm": opts.declared_tool_sigma_mm if declared else None,
                    "tool_offset_sigma_source": (
                        "machine file [tool] offset_sigma_mm" if sigma is not None
                        else "default (a presetter)" if declared
                        else f"not declared: the model's tool is zero and the machine file states "
                             f"no [tool] offset_sigma_mm (prior odds 1, anywhere within "
                             f"+/- {opts.tool_offset_max_mm:g} mm)")}
    from abbe.diagnose.uncertainty import budgets_of_machine, diagnosis_uncertainty
    res.uncertainty = diagnosis_uncertainty(res, *budgets_of_machine(m), draws=mc_draws,
                                            table_cov=tcov)
    return res


@one_blas_thread
def diagnose_positioning(path: Any, axis: str, model: Any = None,
                         options: DiagnoseOptions | None = None,
                         rezeroed: bool = False, mc_draws: int = 0) -> DiagnoseResult:
    """Diagnose repeated positioning runs (ISO 230-2 .dat or laser CSV) of one axis.

    Without ``model`` the model is position-only: the axis' own positioning term
    interpolating the mean deviation of each target (abbe.diagnose.checks.position_only_table).
    """
    from abbe.diagnose.checks import position_only_table, positioning_check
    from abbe.diagnose.outliers import screen
    axis = axis.upper()
    if axis not in AXES:
        raise AbbeInputError(f"axis {axis!r}: expected X, Y or Z", field="axis")
    if model is None:
        c = positioning_check(path, axis, (0.0, 0.0, 0.0), rezeroed=rezeroed)
        ref = [0.0, 0.0, 0.0]
        tg = c.targets
        ref[AXES.index(axis)] = 0.0 if tg.min() <= 0.0 <= tg.max() else float(tg[0])
        c = positioning_check(path, axis, tuple(ref), rezeroed=rezeroed)  # type: ignore[arg-type]
        # outlier runs first: the position-only model is the mean of the runs kept
        (c,), found = screen([c])
        c.meta["outliers_found"] = found
        table = position_only_table(c)
        # the model is these runs' mean: a drift is the change from their mean state
        c.drift_from_table_mean = True
    else:
        table = load_model(model)
        c = positioning_check(path, axis, table.reference_mm, rezeroed=rezeroed)
    from abbe.diagnose.uncertainty import budget_of_positioning_file, diagnosis_uncertainty
    from abbe.diagnose.table_uncertainty import table_covariance
    tcov = table_covariance(model, table)
    res = diagnose(table, [c], options, table_cov=tcov)
    res.uncertainty = diagnosis_uncertainty(res, budget_of_positioning_file(path), None,
                                            draws=mc_draws, model_from_the_data=model is None,
                                            table_cov=tcov)
    return res
