"""The result of :func:`greybox.fit`: the command line's JSON report as Python data."""

from __future__ import annotations

import html
import json
from typing import Any, Optional

import pyarrow as pa

from . import _greybox

__all__ = ["Fit"]

#: Columns of :attr:`Fit.parameters`, each with its type.
PARAMETER_SCHEMA = pa.schema(
    [
        ("name", pa.string()),
        ("value", pa.float64()),
        ("unit", pa.string()),
        ("std_error", pa.float64()),
        ("ci95_low", pa.float64()),
        ("ci95_high", pa.float64()),
        ("std_error_white", pa.float64()),
        ("error_index_percent", pa.float64()),
        ("fixed", pa.bool_()),
        ("start", pa.float64()),
    ]
)

#: Columns of :attr:`Fit.derived`.
DERIVED_SCHEMA = pa.schema(
    [
        ("name", pa.string()),
        ("value", pa.float64()),
        ("unit", pa.string()),
        ("std_error", pa.float64()),
        ("ci95_low", pa.float64()),
        ("ci95_high", pa.float64()),
    ]
)


def _rows(items: list[dict[str, Any]], schema: pa.Schema, derived: bool) -> pa.Table:
    columns: dict[str, list[Any]] = {f.name: [] for f in schema}
    for item in items:
        se = item.get("std_error")
        ci = item.get("ci95")
        if ci is None and derived and item.get("value") is not None and se is not None:
            # A report written before the derived quantities kept their intervals: the
            # normal value ± 1.96 standard errors.
            ci = [item["value"] - 1.96 * se, item["value"] + 1.96 * se]
        for name in columns:
            if name == "ci95_low":
                columns[name].append(ci[0] if ci else None)
            elif name == "ci95_high":
                columns[name].append(ci[1] if ci else None)
            else:
                columns[name].append(item.get(name))
    return pa.table(columns, schema=schema)


class Fit:
    """A fit of a PMSM model to drive logs: the estimates, their uncertainty and the warnings.

    Everything is the command line's JSON report (``greybox fit --json``), which
    :meth:`to_json` returns byte for byte and :meth:`to_dict` parses. Units are SI: ``r_s``
    [Ω] (``ohm``), ``l_s``, ``l_d``, ``l_q`` [H], ``k_e`` [V s/rad] (mechanical), ``k_t``
    [N m/A], ``psi_f`` [V s].
    """

    __slots__ = ("_native", "_dict")

    def __init__(self, native: _greybox.NativeFit) -> None:
        self._native = native
        self._dict: Optional[dict[str, Any]] = None

    def to_json(self) -> str:
        """The JSON report, exactly what ``greybox fit --json`` writes (without its final
        newline); the ``timing`` key differs from run to run."""
        return self._native.json

    def to_dict(self) -> dict[str, Any]:
        """The JSON report as a dict, with exactly the report's keys (a fresh copy)."""
        return json.loads(self._native.json)

    def _report(self) -> dict[str, Any]:
        if self._dict is None:
            self._dict = self.to_dict()
        return self._dict

    @property
    def parameters(self) -> pa.Table:
        """The estimated parameters, one row each (nuisance parameters included):
        ``name, value, unit, std_error, ci95_low, ci95_high, std_error_white,
        error_index_percent, fixed, start``; values in the unit of the row (SI)."""
        return _rows(self._report()["parameters"], PARAMETER_SCHEMA, derived=False)

    @property
    def derived(self) -> pa.Table:
        """Quantities derived from the parameters (``k_t`` [N m/A], ``psi_f`` [V s], with a
        reference temperature the winding and magnet temperatures [°C]):
        ``name, value, unit, std_error, ci95_low, ci95_high`` (the report's 95 % interval: with
        instrumental variables and steady-state fits a quantity of one parameter takes that
        parameter's interval through its function, otherwise value ± t σ at the fit's Student
        quantile)."""
        return _rows(self._report().get("derived", []), DERIVED_SCHEMA, derived=True)

    @property
    def warnings(self) -> list[dict[str, Any]]:
        """The report's warnings, each ``{"code", "message", "untrusted"}``."""
        return list(self._report().get("warnings", []))

    @property
    def trusted(self) -> bool:
        """Whether ``greybox fit`` would exit with 0: converged and no untrusted warning
        (or ``allow_unconverged=True``); ``False`` where it exits with 3."""
        return self._native.trusted

    def value(self, name: str) -> float:
        """The estimate of a parameter or derived quantity by name (e.g. ``"r_s"`` [Ω]).

        Raises ``KeyError`` for a name the report does not have.
        """
        report = self._report()
        for item in [*report["parameters"], *report.get("derived", [])]:
            if item["name"] == name:
                return item["value"]
        raise KeyError(name)

    def svg(self) -> Optional[str]:
        """The fit plot as SVG text (what ``--plot`` writes): measured and simulated currents
        with the speed, residuals, their autocorrelation, the parameter trace and the
        estimates with 95 % intervals; ``None`` for ``method="ls"`` and for the steady-state
        equations (``model="spm-steady"``, or chosen for a slow log), which simulate no currents."""
        return self._native.svg()

    def __str__(self) -> str:
        return self._native.text

    def __repr__(self) -> str:
        names = ", ".join(f"{p['name']}={p['value']:.6g} {p['unit']}" for p in self._report()["parameters"])
        return f"<greybox.Fit {self._report().get('model')}: {names}; trusted={self.trusted}>"

    def _repr_html_(self) -> str:
        svg = self.svg() or ""
        if svg.startswith("<?xml"):
            svg = svg[svg.index("?>") + 2 :]
        return f"<div><pre>{html.escape(self._native.text)}</pre>{svg}</div>"
