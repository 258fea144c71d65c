"""The fleet view: the summary of many logs (:func:`greybox.fit_many`,
:func:`greybox.dask.fit_fleet`, ``greybox fit --each --summary``) keyed by motor and log,
with winding and magnet temperatures inferred from R_s and psi_f (MODEL.md §3) and two flags
per log: ``demagnetised`` and ``r_s_excess``.

>>> import greybox, greybox.fleet
>>> summary = greybox.fit_many("/tmp/fleet-logs", pole_pairs=4)  # doctest: +SKIP
>>> view = greybox.fleet.fleet_view(summary, motor_id=r"(motor\\d+)_log", t0=20,
...                                 temperature="t_winding", magnet_offset=15)  # doctest: +SKIP
>>> greybox.fleet.by_motor(view).to_pandas()  # doctest: +SKIP
"""

from __future__ import annotations

import math
import os
import re
from typing import Any, Mapping, Optional, Union

import pyarrow as pa
import pyarrow.compute as pc

from ._greybox import DataError, OptionError

__all__ = ["ALPHA_COPPER", "BETA_NDFEB", "by_motor", "fleet_view", "log_temperatures"]

#: Temperature coefficient of copper resistance α [1/K] (the crate's ``ALPHA_COPPER``).
ALPHA_COPPER = 0.00393
#: Temperature coefficient of NdFeB remanence β [1/K] (the crate's ``BETA_NDFEB``).
BETA_NDFEB = -0.0011
#: Half-width of a 95 % interval in standard errors: the fallback for a summary written
#: before it had the report's intervals (``NAME_low``, ``NAME_high``, 2026-12-01).
Z95 = 1.959963984540054

Reference = Union[None, float, Mapping[str, float]]


def log_temperatures(paths: list[str], column: str) -> list[float]:
    """The mean of ``column`` (e.g. a measured winding temperature [°C]) over each log file.

    Reads that column only, with pyarrow: Parquet, Arrow IPC (``.arrow``, ``.feather``,
    ``.ipc``), CSV (plain or ``.gz``). Raises :class:`greybox.DataError` naming the file
    and the column when the file cannot be read, lacks the column or the column is empty.
    """
    out = []
    for path in paths:
        try:
            if path.endswith(".parquet"):
                import pyarrow.parquet as pq

                col = pq.read_table(path, columns=[column]).column(column)
            elif path.endswith((".arrow", ".feather", ".ipc")):
                import pyarrow.feather as feather

                col = feather.read_table(path, columns=[column]).column(column)
            else:
                import pyarrow.csv as pacsv

                opts = pacsv.ConvertOptions(include_columns=[column])
                col = pacsv.read_csv(path, convert_options=opts).column(column)
        except (OSError, KeyError, pa.ArrowException) as e:
            raise DataError(f"{path}: cannot read column `{column}`: {e}") from None
        mean = pc.mean(col).as_py()
        if mean is None or not math.isfinite(mean):
            raise DataError(f"{path}: column `{column}` has no finite values")
        out.append(float(mean))
    return out


def _motor_ids(summary: pa.Table, motor_id: str) -> list[str]:
    """Each row's motor: the column ``motor_id``, else the one group of that regex on the log."""
    if motor_id in summary.column_names:
        return [str(v) for v in summary.column(motor_id).to_pylist()]
    try:
        pattern = re.compile(motor_id)
    except re.error as e:
        raise OptionError(
            f"invalid option `motor_id`: {motor_id!r} is no column and no regular expression ({e})"
        ) from None
    if pattern.groups != 1:
        raise OptionError(
            f"invalid option `motor_id`: {motor_id!r} is no column of the summary and not a regular expression "
            f"with exactly one group (it has {pattern.groups})"
        )
    ids = []
    for log in summary.column("log").to_pylist():
        m = pattern.search(log)
        if m is None or m.group(1) is None:
            raise OptionError(f"invalid option `motor_id`: {motor_id!r} does not match the log {log!r}")
        ids.append(m.group(1))
    return ids


def _temperatures(summary: pa.Table, temperature: Any) -> list[Optional[float]]:
    """Each row's measured winding temperature [°C] (``None`` where none is given)."""
    logs = summary.column("log").to_pylist()
    if temperature is None:
        return [None] * len(logs)
    if isinstance(temperature, str):
        if temperature in summary.column_names:
            return summary.column(temperature).to_pylist()
        return log_temperatures([os.fspath(p) for p in logs], temperature)
    table = pa.table(temperature)
    if not {"log", "temperature"} <= set(table.column_names):
        raise OptionError("invalid option `temperature`: a table needs the columns `log` and `temperature` [°C]")
    known = dict(zip(table.column("log").to_pylist(), table.column("temperature").to_pylist()))
    missing = [log for log in logs if log not in known]
    if missing:
        raise DataError(f"the temperature table has no row for the log {missing[0]!r}")
    return [known[log] for log in logs]


def _column(summary: pa.Table, name: str) -> list[Optional[float]]:
    """A parameter's column of the summary by its name (``r_s`` → ``r_s [Ω]``), nulls kept."""
    for c in summary.column_names:
        if c.split(" [")[0] == name:
            return summary.column(c).to_pylist()
    raise DataError(f"the summary has no column `{name} [unit]` (a summary of fit_many or fit --each --summary)")


def _interval(summary: pa.Table, name: str) -> list[tuple[Optional[float], Optional[float]]]:
    """The report's 95 % interval of a parameter per log (``NAME_low``, ``NAME_high``; an end
    the report has not, e.g. an infinite one, stays null), or ``value ± Z95 se`` for every
    log of a summary without interval columns (written before they existed)."""
    try:
        low, high = _column(summary, name + "_low"), _column(summary, name + "_high")
    except DataError:
        value, se = _column(summary, name), _column(summary, name + "_se")
        return [(v - Z95 * s, v + Z95 * s) if _ok(v, s) else (None, None) for v, s in zip(value, se)]
    return [(lo if _ok(lo) else None, hi if _ok(hi) else None) for lo, hi in zip(low, high)]


def _given(value: Reference, motor: str, option: str) -> Optional[float]:
    """A motor's given reference value: one for all motors, or by motor id."""
    if value is None:
        return None
    if isinstance(value, Mapping):
        if motor not in value:
            raise OptionError(f"invalid option `{option}`: no value for the motor {motor!r}")
        return float(value[motor])
    return float(value)


def _ok(*values: Optional[float]) -> bool:
    return all(v is not None and math.isfinite(v) for v in values)


def _reference(rows: list[dict], key: str, coef: float, t0: float, sd_t: float, n: int) -> tuple[float, float]:
    """A motor's value at T_0 and its standard error from its first ``n`` usable logs: the
    mean of ``value / (1 + coef (T − T_0))``; the error from the fits' errors and ``sd_t``."""
    use = [r for r in rows if _ok(r[key], r[key + "_se"]) and (r["temp"] is None or _ok(r["temp"]))][:n]
    if not use:
        return math.nan, math.nan
    scaled = [r[key] / (1 + coef * (r["temp"] - t0)) if r["temp"] is not None else r[key] for r in use]
    ref = sum(scaled) / len(scaled)
    sd_temp = abs(coef) * ref * sd_t if use[0]["temp"] is not None else 0.0
    se2 = sum(r[key + "_se"] ** 2 for r in use) / len(use) ** 2 + sd_temp**2 / len(use)
    return ref, math.sqrt(se2)


def _check(
    value, se, ref, ref_se, coef, temp, t0, sd_t, z, sign
) -> tuple[Optional[float], Optional[float], Optional[bool]]:
    """The expected value at ``temp``, the deviation in standard errors (``sign`` +1: above,
    −1: below) and whether it is beyond ``z``."""
    if not _ok(value, se, ref):
        return None, None, None
    c = 1 + coef * (temp - t0) if temp is not None else 1.0
    expected = ref * c
    sd_temp = abs(coef) * ref * sd_t if temp is not None else 0.0
    sigma = math.sqrt(se**2 + sd_temp**2 + (ref_se * c) ** 2)
    score = sign * (value - expected) / sigma if sigma > 0 else math.inf * sign * (value - expected)
    return expected, score, bool(score > z)


def fleet_view(
    summary: pa.Table,
    *,
    motor_id: str,
    t0: float = 20.0,
    r_s0: Reference = None,
    psi_f0: Reference = None,
    temperature: Any = None,
    temperature_sd: float = 1.0,
    magnet_offset: float = 0.0,
    reference_logs: int = 3,
    z: float = 3.0,
    alpha_cu: float = ALPHA_COPPER,
    beta_magnet: float = BETA_NDFEB,
) -> pa.Table:
    """The fleet view: one row per log, keyed by ``motor`` and ``log``, in the summary's order.

    ``summary``: the table of :func:`greybox.fit_many` (or ``fit --each --summary``, read
    with ``pyarrow.csv``): ``log``, ``status``, ``r_s [Ω]``, ``k_e [V s/rad]``, ``psi_f
    [V s]`` and their ``_se``. ``motor_id``: a column of the summary, or a regular
    expression with one group, searched in each ``log`` path (``r"(motor\\d+)_log"``); a
    log it does not match is an :class:`greybox.OptionError` naming the log. ``t0``: the
    reference temperature T_0 [°C]. ``r_s0`` [Ω], ``psi_f0`` [V s]: each motor's values at
    T_0, one for all or a dict by motor id; ``None`` (the default): taken from the motor's
    own first ``reference_logs`` usable logs (in the summary's order; these are assumed
    healthy), each brought to T_0 by its measured temperature. ``temperature``: the
    measured winding temperature of each log [°C]: a column of the summary, or the name of
    a column in the log files (its mean per log, read by :func:`log_temperatures`), or a
    table with columns ``log`` and ``temperature``; ``None``: no measurement (then the
    references are the first logs' plain means and the flags compare values as if at equal
    temperatures). ``temperature_sd``: the standard uncertainty of one measured temperature
    [K]. ``magnet_offset``: how much cooler than the measured winding the magnets are [K]
    (T_m = T − offset). ``z``: the threshold in combined standard errors (3: a false flag
    in ~1 of 700 healthy logs). ``alpha_cu``, ``beta_magnet``: the coefficients [1/K].

    Temperatures (MODEL.md §3): ``t_winding = T_0 + (r_s / r_s0 − 1) / α``, ``t_magnet =
    T_0 + (psi_f / psi_f0 − 1) / β`` [°C], each with its standard error from the fit's.

    Flags, per log (null for a failed log or a missing reference):

    - ``r_s_excess``: ``r_s − r_s0 (1 + α (T − T_0)) > z σ``, T the measured temperature,
      ``σ² = se(r_s)² + (α r_s0 σ_T)² + (se(r_s0) (1 + α (T − T_0)))²`` (fit, thermometer,
      reference): the resistance is higher than its temperature explains (a connection or
      winding fault). Without ``temperature`` only ``r_s0`` itself is the expectation.
    - ``demagnetised``: ``psi_f0 (1 + β (T_m − T_0)) − psi_f > z σ``, σ as above with β,
      psi_f and T_m: the flux, hence K_e (∝ psi_f), has fallen below the motor's own
      earlier level at equal magnet temperature.

    Columns: ``motor, log, status, temperature [°C]``, ``r_s [Ω]`` with ``r_s_low,
    r_s_high`` (the fit's 95 % interval, from the summary's columns of that name; ``± 1.96``
    standard errors for a summary written before it had them), ``r_s_t0 [Ω]`` (brought to
    T_0 by the measured temperature), ``k_e [V s/rad]`` with ``k_e_low, k_e_high`` and ``k_e_t0``, ``psi_f [V s]``, ``r_s0 [Ω]``,
    ``psi_f0 [V s]`` (given or referenced), ``t_winding [°C]``, ``t_winding_se``,
    ``t_magnet [°C]``, ``t_magnet_se``, ``r_s_expected [Ω]``, ``r_s_excess_z``,
    ``r_s_excess``, ``psi_f_expected [V s]``, ``psi_f_drop_z``, ``demagnetised``.

    Raises :class:`greybox.OptionError` for a bad ``motor_id``, reference or threshold,
    :class:`greybox.DataError` for a summary without the columns or an unreadable log.
    """
    if reference_logs < 1:
        raise OptionError("invalid option `reference_logs`: at least 1 log")
    if not (temperature_sd >= 0 and z > 0):
        raise OptionError("invalid option: `temperature_sd` must be ≥ 0 K and `z` > 0")
    if "log" not in summary.column_names:
        raise DataError("the summary has no column `log`")
    motors = _motor_ids(summary, motor_id)
    temps = _temperatures(summary, temperature)
    cols = {k: _column(summary, k) for k in ("r_s", "r_s_se", "k_e", "k_e_se", "psi_f", "psi_f_se")}
    cols |= {k + "_ci": _interval(summary, k) for k in ("r_s", "k_e")}
    status = summary.column("status").to_pylist() if "status" in summary.column_names else ["ok"] * len(motors)
    rows = []
    for i, (motor, temp) in enumerate(zip(motors, temps)):
        row = {k: (v[i] if status[i] != "failed" else None) for k, v in cols.items()}
        row |= {k: (None, None) for k in ("r_s_ci", "k_e_ci") if row[k] is None}
        t_mag = temp - magnet_offset if temp is not None else None
        rows.append({**row, "motor": motor, "temp": temp, "t_mag": t_mag, "i": i})
    by_motor_rows: dict[str, list[dict]] = {}
    for r in rows:
        by_motor_rows.setdefault(r["motor"], []).append(r)
    sd_t = temperature_sd
    for motor, group in by_motor_rows.items():
        given_r, given_p = _given(r_s0, motor, "r_s0"), _given(psi_f0, motor, "psi_f0")
        ref_r = (given_r, 0.0) if given_r is not None else _reference(group, "r_s", alpha_cu, t0, sd_t, reference_logs)
        mags = [{**r, "temp": r["t_mag"]} for r in group]
        ref_p = (
            (given_p, 0.0) if given_p is not None else _reference(mags, "psi_f", beta_magnet, t0, sd_t, reference_logs)
        )
        for r in group:
            r["r_s0"], r["psi_f0"] = ref_r[0], ref_p[0]
            r["r_exp"], r["r_z"], r["r_flag"] = _check(
                r["r_s"], r["r_s_se"], ref_r[0], ref_r[1], alpha_cu, r["temp"], t0, sd_t, z, +1
            )
            r["p_exp"], r["p_z"], r["p_flag"] = _check(
                r["psi_f"], r["psi_f_se"], ref_p[0], ref_p[1], beta_magnet, r["t_mag"], t0, sd_t, z, -1
            )
    return _table(summary, rows, status, t0, alpha_cu, beta_magnet)


def _table(summary, rows, status, t0, alpha, beta) -> pa.Table:
    """The view's columns from the per-row dicts."""

    def col(f):
        return pa.array([f(r) for r in rows], pa.float64())

    def temp(key, ref, coef):
        return lambda r: t0 + (r[key] / r[ref] - 1) / coef if _ok(r[key], r[ref]) else None

    def temp_se(key, ref, coef):
        return lambda r: r[key + "_se"] / abs(coef * r[ref]) if _ok(r[key + "_se"], r[ref]) else None

    def at_t0(key, t, coef):
        return lambda r: r[key] / (1 + coef * (r[t] - t0)) if _ok(r[key]) and r[t] is not None else r[key]

    k_ratio = [r["k_e"] / r["psi_f"] if _ok(r["k_e"], r["psi_f"]) and r["psi_f"] else None for r in rows]
    psi_t0 = [at_t0("psi_f", "t_mag", beta)(r) for r in rows]
    return pa.table(
        {
            "motor": pa.array([r["motor"] for r in rows], pa.string()),
            "log": summary.column("log"),
            "status": pa.array(status, pa.string()),
            "temperature [°C]": col(lambda r: r["temp"]),
            "r_s [Ω]": col(lambda r: r["r_s"]),
            "r_s_low [Ω]": col(lambda r: r["r_s_ci"][0]),
            "r_s_high [Ω]": col(lambda r: r["r_s_ci"][1]),
            "r_s_t0 [Ω]": col(at_t0("r_s", "temp", alpha)),
            "k_e [V s/rad]": col(lambda r: r["k_e"]),
            "k_e_low [V s/rad]": col(lambda r: r["k_e_ci"][0]),
            "k_e_high [V s/rad]": col(lambda r: r["k_e_ci"][1]),
            "k_e_t0 [V s/rad]": pa.array([p * k if _ok(p, k) else None for p, k in zip(psi_t0, k_ratio)], pa.float64()),
            "psi_f [V s]": col(lambda r: r["psi_f"]),
            "r_s0 [Ω]": col(lambda r: r["r_s0"] if _ok(r["r_s0"]) else None),
            "psi_f0 [V s]": col(lambda r: r["psi_f0"] if _ok(r["psi_f0"]) else None),
            "t_winding [°C]": col(temp("r_s", "r_s0", alpha)),
            "t_winding_se [°C]": col(temp_se("r_s", "r_s0", alpha)),
            "t_magnet [°C]": col(temp("psi_f", "psi_f0", beta)),
            "t_magnet_se [°C]": col(temp_se("psi_f", "psi_f0", beta)),
            "r_s_expected [Ω]": col(lambda r: r["r_exp"]),
            "r_s_excess_z": col(lambda r: r["r_z"]),
            "r_s_excess": pa.array([r["r_flag"] for r in rows], pa.bool_()),
            "psi_f_expected [V s]": col(lambda r: r["p_exp"]),
            "psi_f_drop_z": col(lambda r: r["p_z"]),
            "demagnetised": pa.array([r["p_flag"] for r in rows], pa.bool_()),
        }
    )


def by_motor(view: pa.Table) -> pa.Table:
    """One row per motor of a :func:`fleet_view`: ``motor``, ``logs`` (count), ``r_s0 [Ω]``,
    ``psi_f0 [V s]``, the largest ``r_s_excess_z`` and ``psi_f_drop_z``, and whether any
    of its logs is flagged ``demagnetised`` or ``r_s_excess``; sorted by motor."""
    agg = view.group_by("motor", use_threads=False).aggregate(
        [
            ("log", "count"),
            ("r_s0 [Ω]", "first"),
            ("psi_f0 [V s]", "first"),
            ("r_s_excess_z", "max"),
            ("psi_f_drop_z", "max"),
            ("demagnetised", "any"),
            ("r_s_excess", "any"),
        ]
    )
    names = ["logs", "r_s0 [Ω]", "psi_f0 [V s]", "r_s_excess_z_max", "psi_f_drop_z_max", "demagnetised", "r_s_excess"]
    # pyarrow puts the key first (≥ 15) or last (older): name the aggregates by position.
    keys = [c for c in agg.column_names if c == "motor"]
    aggs = agg.drop(keys)
    return pa.table([agg.column("motor")] + aggs.columns, names=["motor"] + names).sort_by("motor")
