"""greybox: permanent-magnet synchronous motor parameters from drive logs.

Estimates the stator resistance ``r_s`` [Ω], the inductance ``l_s`` (or ``l_d``, ``l_q``)
[H] and the back-EMF constant ``k_e`` [V s/rad, mechanical], hence the torque constant
``k_t`` [N m/A] and the magnet flux ``psi_f`` [V s], by the prediction-error method on an
exact sampled-data model (Tenerz 2011, sections 5.2–5.3). The work is done by the Rust
library; options are the command line's flags as keyword arguments (``dead_time="estimate"``
for ``--dead-time estimate``, ``fixed_x0=True`` for ``--fixed-x0``, docs/options.md). The
fits' keywords are converted once into the library's typed request, the one the command
line builds from its flags: the same defaults, checks and results, and an error names the
keyword (``voltage="referense": expected actual or reference``).

>>> import greybox
>>> fit = greybox.fit("data/sample.csv.gz", pole_pairs=4)  # doctest: +SKIP
>>> fit.parameters.to_pandas()  # doctest: +SKIP

Errors are :class:`Error` subclasses: :class:`DataError` (a log that cannot be read or
used), :class:`OptionError` (an invalid option), :class:`FitError` (the fit failed).
"""

from __future__ import annotations

import json
import os
import tempfile
from typing import Any, Iterable, NamedTuple, Optional, Sequence, Union

import pyarrow as pa

from . import _greybox
from ._fit import Fit
from ._greybox import DataError, Error, FitError, OptionError

__all__ = [
    "DataError",
    "Error",
    "Fit",
    "FitError",
    "INNOVATION_RATIO_LIMIT",
    "OptionError",
    "Report",
    "TrackRun",
    "fit",
    "fleet",
    "fit_many",
    "fluxmap",
    "mechanics",
    "saturation",
    "simulate",
    "standstill",
    "track",
    "validate",
]

__version__: str = _greybox.__version__


def __dir__() -> list[str]:
    """The package's public names (``__all__`` and ``__version__``), not the modules it
    imports for its own use (PEP 562)."""
    return sorted([*__all__, "__version__"])

PathLike = Union[str, "os.PathLike[str]"]


def _is_path(obj: Any) -> bool:
    return isinstance(obj, (str, os.PathLike))


def _arrow(obj: Any) -> Any:
    """An object offering ``__arrow_c_stream__``: the table itself (pyarrow, polars ≥ 1.0,
    pandas ≥ 2.2 and any other Arrow PyCapsule producer), else converted by pyarrow."""
    if hasattr(obj, "__arrow_c_stream__"):
        return obj
    if hasattr(obj, "to_arrow"):  # polars before the PyCapsule interface
        return obj.to_arrow()
    try:
        import pandas as pd

        if isinstance(obj, pd.DataFrame):
            return pa.Table.from_pandas(obj, preserve_index=False)
    except ImportError:
        pass
    try:
        return pa.table(obj)
    except (TypeError, ValueError, pa.ArrowException) as e:
        raise DataError(f"not a log: {type(obj).__name__} is neither a path nor an Arrow-like table ({e})") from None


def fit(
    log: Union[PathLike, Any, Sequence[Union[PathLike, Any]]],
    *,
    pole_pairs: Union[int, str],
    model: str = "spm",
    name: Optional[str] = None,
    **options: Any,
) -> Fit:
    """Fits a PMSM model to one drive log, or to several jointly (shared parameters).

    ``log``: a path (CSV plain or gzip, Parquet, Arrow IPC), an Arrow-like table in memory
    (pyarrow Table or RecordBatchReader, polars or pandas DataFrame; columns ``t`` [s],
    ``ud, uq`` [V], ``id, iq`` [A], ``w_m`` [rad/s, mechanical], optional ``theta_m``
    [rad, mechanical], ``ud_ref, uq_ref`` [V]; other names by ``col_*`` options), or a list
    of them. ``pole_pairs``: n_p, or ``"auto"``. ``model``: ``"spm"`` (r_s, l_s, k_e) or
    ``"ipm"`` (r_s, l_d, l_q, k_e). ``name``: the name of a table in the report (default
    ``"table"``). ``options``: the flags of ``greybox fit`` (docs/cli.md) as keywords, e.g.
    ``voltage="reference"``, ``delay="estimate"``, ``dead_time="estimate"``,
    ``hold="stator"``, ``fix={"r_s": 0.9}``, ``bounds={"l_s": (1e-4, 1e-2)}``,
    ``precision={"r_s": "1%", "k_e": "0.1%"}`` (or ``"off"``: the accuracy a trusted fit
    must reach, three standard errors, a number without ``%`` a fraction; the steady-state
    fit's default 0.5 % and 0.05 %),
    ``from_=0.5`` (``from`` is a Python keyword: a trailing underscore is dropped).
    The file outputs (``json``, ``plot``, ``residuals``) are refused: see :class:`Fit`.

    The GIL is released while the logs are read and fitted: fits in threads run in parallel.

    Raises :class:`OptionError` for an invalid option (naming its keyword),
    :class:`DataError` for a log that cannot be read (a missing column with the keywords
    that name the header's look-alikes, e.g. ``col_id="Id"``), :class:`FitError` when the
    fit fails.
    """
    sources, names = _sources(log, name or "table")
    return Fit(_greybox.fit(sources, names, _flags(pole_pairs=pole_pairs, model=model, **options)))


def _sources(logs: Any, base: str) -> tuple[list[Any], list[str]]:
    """The logs as the native module takes them: ``logs`` (one, or a list or tuple) each a
    path (as ``str``) or an Arrow C stream, and a name per log: a path itself, a table
    ``base`` when it is the only table, else ``base1``, ``base2``, … in the tables' order."""
    items = list(logs) if isinstance(logs, (list, tuple)) else [logs]
    sources = [os.fspath(x) if _is_path(x) else _arrow(x) for x in items]
    tables = sum(1 for x in items if not _is_path(x))
    it = iter([base if tables == 1 else f"{base}{k + 1}" for k in range(tables)])
    return sources, [s if isinstance(s, str) else next(it) for s in sources]


def _flags(**options: Any) -> dict[str, Any]:
    """The options with a trailing underscore dropped (``from_`` → ``from``)."""
    return {k[:-1] if k.endswith("_") else k: v for k, v in options.items()}


def _paths(logs: Union[PathLike, Iterable[PathLike]]) -> list[str]:
    """A folder or glob (as ``fit --each``), a path, or a list of paths."""
    if _is_path(logs):
        path = os.fspath(logs)  # type: ignore[arg-type]
        return [path] if os.path.isfile(path) else list(_greybox.expand_logs(path))
    return [os.fspath(p) for p in logs]  # type: ignore[union-attr]


def _summary_table(records: list[str]) -> pa.Table:
    """The ``--summary`` table of summary records (JSON, from the native ``fit_records``)."""
    columns = _greybox.summary_columns(records)
    types = {"string": pa.string(), "int64": pa.int64(), "bool": pa.bool_(), "float64": pa.float64()}
    return pa.table({n: pa.array(v, type=types[t]) for n, t, v in columns})


def fit_many(
    logs: Union[PathLike, Iterable[PathLike]],
    *,
    pole_pairs: Union[int, str],
    model: str = "spm",
    threads: Optional[int] = None,
    **options: Any,
) -> pa.Table:
    """Fits each log on its own with the same options, in parallel, as ``greybox fit --each``.

    ``logs``: a list of paths, or a folder or glob (its logs as ``--each`` finds them).
    ``threads``: how many logs at a time (default ``RAYON_NUM_THREADS`` or the cores).
    Returns one row per log with the columns of ``--summary`` (docs/cli.md): ``log, name,
    status`` (``ok``, ``untrusted``, ``failed``), ``error``, ``pole_pairs, hold, converged``,
    ``NAME [unit]``, ``NAME_se [unit]`` and the report's 95 % interval ``NAME_low [unit]``,
    ``NAME_high [unit]`` per parameter and derived quantity (SI),
    ``fit_OUTPUT [%]``, ``warnings``, ``time [s]``. A log that cannot be read or fitted is a
    ``failed`` row with its ``error``, never an exception.

    Raises :class:`OptionError` for an invalid option (before any log is read) or a folder
    or glob without logs.
    """
    paths = _paths(logs)
    names = _greybox.log_names(paths)
    flags = _flags(pole_pairs=pole_pairs, model=model, **options)
    return _summary_table(_greybox.fit_records(paths, names, flags, threads))


def _params_file(params: Any, stack: Any) -> str:
    """A path to the JSON report of ``params`` (a path, a :class:`Fit` or a report dict)."""
    if _is_path(params):
        return os.fspath(params)
    text = params.to_json() if isinstance(params, Fit) else json.dumps(params)
    f = stack.enter_context(tempfile.NamedTemporaryFile("w", suffix=".json", delete=False))
    f.write(text)
    f.close()
    stack.callback(os.unlink, f.name)
    return f.name


def validate(log: Union[PathLike, Sequence[PathLike]], *, params: Any, **options: Any) -> dict[str, Any]:
    """Compares a saved fit with logs it was not fitted on, as ``greybox validate``.

    ``params``: a :class:`Fit`, its report dict, or the path of a report (``--json``).
    ``options``: the flags of ``greybox validate`` (``pole_pairs``, ``hold``, ``from_``, …).
    Returns the report of ``validate --json``: ``model, pole_pairs, hold, theta`` and per
    log its ``metrics`` (fit [%], residual RMS [A], FPE, AIC, whiteness).

    Raises :class:`OptionError`, :class:`DataError` or :class:`FitError`.
    """
    import contextlib

    paths = [os.fspath(p) for p in (log if isinstance(log, (list, tuple)) else [log])]
    with contextlib.ExitStack() as stack:
        return json.loads(_greybox.validate(paths, _flags(params=_params_file(params, stack), **options)))


class TrackRun(NamedTuple):
    """One log (or segment) tracked by an online estimator (the MRAS or the Kalman filter)."""

    #: The log's path as given (``PATH#k`` for segment k of a log split at its gaps).
    name: str
    #: The estimates after the last sample: ``k_e`` [V s/rad], ``k_t`` [N m/A], ``r_s`` [Ω]
    #: (``estimator="ekf"``: also ``k_e_se``, ``k_t_se``, ``r_s_se``, standard errors).
    final: dict[str, float]
    #: Every step: ``t`` [s], ``k_e`` [V s/rad], ``r_s`` [Ω] (``estimator="ekf"``: also
    #: ``k_e_se``, ``r_s_se``; with ``t0=`` and ``r_s_t0=`` or ``psi_f_t0=``: ``t_winding``,
    #: ``t_magnet`` [°C] and their ``_se`` [K]).
    trajectory: pa.Table


def track(log: Union[PathLike, Sequence[PathLike]], *, pole_pairs: int, **options: Any) -> list[TrackRun]:
    """Runs an online estimator over each log, as ``greybox track``: the extended Kalman
    filter of R_s and K_e (the default, Simon 2006 §13.2), whose trajectory and final
    estimates carry standard errors (``k_e_se`` [V s/rad], ``r_s_se`` [Ω]; the final ones
    also ``k_t_se`` [N m/A]), or with ``estimator="mras"`` the thesis' MRAS (thesis 5.1),
    without them.

    ``options``: its flags, e.g. ``l_s=5e-3`` [H] or ``params=`` a :class:`Fit`, a report
    dict or path; the filter's ``current_noise`` [A], ``r_s_walk``, ``k_e_walk``; the MRAS's
    ``adaptation``, ``tau_ke`` [s], ``gamma_ke``, … (each refused with the other
    estimator). Returns one :class:`TrackRun` per log.

    Raises :class:`OptionError`, :class:`DataError` or :class:`FitError`.
    """
    import contextlib

    paths = [os.fspath(p) for p in (log if isinstance(log, (list, tuple)) else [log])]
    with contextlib.ExitStack() as stack:
        if options.get("params") is not None:
            options["params"] = _params_file(options["params"], stack)
        runs = _greybox.track(paths, _flags(pole_pairs=pole_pairs, **options))
    return [
        TrackRun(name, _final(k_e, k_t, r_s, k_e_se, r_s_se, ratio), pa.Table.from_batches([batch]))
        for name, (k_e, k_t, r_s, k_e_se, r_s_se, ratio), batch in runs
    ]


#: The largest ``innovation_ratio`` of a trusted run of either estimator (``greybox track``'s
#: exit 3 above it; docs/cli.md): ``greybox::online::INNOVATION_RATIO_LIMIT``.
INNOVATION_RATIO_LIMIT: float = _greybox.INNOVATION_RATIO_LIMIT


def _final(
    k_e: float,
    k_t: float,
    r_s: float,
    k_e_se: Optional[float],
    r_s_se: Optional[float],
    ratio: Optional[float],
) -> dict[str, Any]:
    """A run's final estimates, with their standard errors where the estimator gives them,
    and the run's self-check: ``innovation_ratio`` (1 when its model and noise level are
    right; the Kalman filter's innovations, the MRAS's one-step predictions at its running
    estimates) and ``trusted`` (the ratio at most :data:`INNOVATION_RATIO_LIMIT`)."""
    final: dict[str, Any] = {"k_e": k_e, "k_t": k_t, "r_s": r_s}
    if k_e_se is not None and r_s_se is not None:
        final.update(k_e_se=k_e_se, k_t_se=k_e_se * 1.5**0.5, r_s_se=r_s_se)
    if ratio is not None:
        final.update(innovation_ratio=ratio, trusted=bool(ratio <= INNOVATION_RATIO_LIMIT))
    return final


def simulate(scenario: Optional[str] = None, **options: Any) -> tuple[pa.Table, dict[str, Any]]:
    """Simulates a closed-loop servo drive (thesis ch. 4), as ``greybox simulate``.

    ``scenario``: ``"exp1"`` … ``"exp6"``; or ``config=`` a scenario dict or file.
    ``options``: ``motor`` (``"spm"``, ``"ipm"``), ``seed``, ``duration`` [s],
    ``set={"motor.r_s": 1.1}`` (each field by its path). Returns the log as a table (``t``
    [s], then ``ud, uq`` [V], ``id, iq`` [A], ``w_m`` [rad/s], …, as the written log) and the
    truth (the ``.truth.json`` file's dict).

    Raises :class:`OptionError` for an unknown scenario, field or value, :class:`FitError`
    when the simulation diverges.
    """
    import contextlib

    with contextlib.ExitStack() as stack:
        config = options.pop("config", None)
        if config is not None:
            options["config"] = _params_file(config, stack)
        if isinstance(options.get("set"), dict):
            options["set"] = [f"{k}={json.dumps(v)}" for k, v in options["set"].items()]
        batch, truth = _greybox.simulate(_flags(scenario=scenario, **options))
    return pa.Table.from_batches([batch]), json.loads(truth)


class Report(NamedTuple):
    """The report of a fit of issue 33 (``fluxmap``, ``saturation``, ``standstill``,
    ``mechanics``): its JSON as a dict, and why it is not to be trusted."""

    #: The report, as the command's ``--json`` writes it.
    report: dict[str, Any]
    #: The codes of the reasons it is not to be trusted (the command line's exit code 3);
    #: empty when trusted.
    untrusted: list[str]

    @property
    def trusted(self) -> bool:
        """Whether the fit is to be trusted (``untrusted`` empty)."""
        return not self.untrusted


def _report(command: str, logs: Any, options: dict[str, Any]) -> Report:
    """Runs the fit ``command`` on ``logs`` (paths, or Arrow tables read in memory as
    :func:`fit` reads them, named ``table``, ``table2``, …) with the keyword ``options``
    (each checked once by the native module, a wrong one refused naming it)."""
    sources, names = _sources(logs, "table")
    text, untrusted = _greybox.report(command, sources, names, _flags(**options))
    return Report(json.loads(text), list(untrusted))


def fluxmap(map: Any, **options: Any) -> Report:
    """Fits the saturation model with cross-saturation (Hinkkanen et al., IEEE Trans. Ind.
    Appl. 53(3) 2017) to a measured flux map, as ``greybox fluxmap``: a path (``.npz``, or
    CSV, Parquet, Arrow with ``i_d, i_q`` [A], ``psi_d, psi_q`` [V s], one operating point
    per row) or an Arrow-like table with those columns, read in memory.

    ``options``: ``exponents=(S, T, U, V)``; ``col_id``, ``col_iq``, ``col_psid``,
    ``col_psiq``, ``delimiter``; ``col_torque`` (a measured torque [N m], default
    ``torque``) with ``pole_pairs`` compares it with the model's torque
    ``1.5 n_p (psi_d i_q - psi_q i_d)`` (the report's ``torque``). Returns a
    :class:`Report`: coefficients with standard errors, the rms flux residual against the
    map's range, inductances, the no-load flux and incremental inductances checked
    against the map.

    Raises :class:`OptionError`, :class:`DataError` or :class:`FitError`.
    """
    return _report("fluxmap", map, options)


def saturation(log: Any, *, pole_pairs: int, **options: Any) -> Report:
    """Fits the saturated IPM model to drive logs beside the linear IPM fit that starts it,
    as ``greybox saturation`` (docs/saturation.md).

    ``log``: a path, an Arrow table, or a list of them (fitted jointly). ``options``:
    ``exponents=(S, T, U, V)`` and the column and unit flags of :func:`fit`. Returns a
    :class:`Report` (``linear``, ``fit``, ``model``, ``operating_points``).

    Raises :class:`OptionError`, :class:`DataError` or :class:`FitError`.
    """
    return _report("saturation", log, dict(pole_pairs=pole_pairs, **options))


def standstill(log: Any, *, pole_pairs: int, **options: Any) -> Report:
    """Fits ``R_s`` [Ω], the excited axes' inductances [H] and the inverter's voltage error
    ``v_dt`` [V] to locked-rotor logs, as ``greybox standstill`` (docs/standstill.md).

    ``options``: ``terminal=True`` (the measured voltage), ``delay`` [samples], ``width``
    [A], ``col_temperature`` (a winding-temperature column [°C]: ``r_s`` at 20 °C). Returns
    a :class:`Report` (``fit``, ``axes``, ``injection_for_one_percent`` [s], …). The two
    halves of the logs are refitted alone; where they disagree beyond their intervals (a
    winding heating without its temperature column) the fit carries the untrusted warning
    ``segments_disagree`` (Cochran's Q, family level 1e-3; docs/standstill.md).

    Raises :class:`OptionError`, :class:`DataError` or :class:`FitError`.
    """
    return _report("standstill", log, dict(pole_pairs=pole_pairs, **options))


def mechanics(log: Any, *, pole_pairs: int, **options: Any) -> Report:
    """Fits inertia ``j`` [kg m²], viscous ``b`` [N m s/rad] and Coulomb ``t_c`` [N m]
    friction, and on request a gravity load ``mgl`` and a constant load ``t_0`` [N m], to
    the speed and angle of drive logs, as ``greybox mechanics`` (docs/mechanics.md).

    ``options``: ``k_t`` [N m/A] (else the electrical model is fitted first), ``gravity``,
    ``constant_load``, ``per_log`` (friction per log), ``window`` [s], ``coulomb_speed``
    [rad/s] or ``"estimate"`` (the default: the lowest loss over the logs' speed range),
    ``col_load``; a linear axis: ``lead`` [m per motor revolution: a screw, rack or belt]
    or ``pole_pitch`` [m: a linear motor, speed and position in m/s and m], ``k_f`` [N/A],
    reported as mass ``m`` [kg], ``b`` [N s/m], ``f_c`` and ``f_0`` [N]. Returns a
    :class:`Report` (``electrical``, ``motor``, ``mechanics``).

    Raises :class:`OptionError`, :class:`DataError` or :class:`FitError`.
    """
    return _report("mechanics", log, dict(pole_pairs=pole_pairs, **options))


from . import fleet  # noqa: E402  (uses the errors above; pyarrow only)
