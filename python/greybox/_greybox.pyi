"""Type stubs of the native module ``greybox._greybox`` (Rust, pyo3): private, used by the
public functions of :mod:`greybox`. Options arrive as the command line's flags (``argv``)."""

from typing import Any, Optional

import pyarrow as pa

__version__: str
INNOVATION_RATIO_LIMIT: float

class Error(Exception):
    """Any error of greybox; the message is the command line's."""

class DataError(Error):
    """A log that cannot be read or used (missing file or column, bad value, time steps)."""

class OptionError(Error):
    """An invalid option (unknown keyword, bad value, a combination the fit cannot honour)."""

class FitError(Error):
    """The fit or the simulation failed (diverged, numerical failure, optimiser error)."""

class NativeFit:
    """A finished fit: its JSON report, printed table and plot."""

    @property
    def json(self) -> str:
        """The JSON report, as ``greybox fit --json`` writes it (no final newline)."""
    @property
    def text(self) -> str:
        """The report as the aligned table ``greybox fit`` prints."""
    @property
    def markdown(self) -> str:
        """The report as Markdown."""
    @property
    def trusted(self) -> bool:
        """Whether ``greybox fit`` would exit 0 (3 otherwise)."""
    def svg(self) -> Optional[str]:
        """The fit plot (SVG text); ``None`` for ``--method ls``."""

def fit(sources: list[Any], names: list[str], options: dict[str, Any]) -> NativeFit:
    """Fits the logs ``sources`` (paths as ``str``, or Arrow C stream objects named by
    ``names``) jointly with the keyword ``options`` of :func:`greybox.fit`; GIL released."""

def fit_records(
    paths: list[str], names: list[str], options: dict[str, Any], threads: Optional[int] = None
) -> list[str]:
    """Fits each log on its own (``fit --each``); one summary record (JSON) per log."""

def summary_columns(records: list[str]) -> list[tuple[str, str, list[Any]]]:
    """The ``--summary`` columns ``(header, arrow type, values)`` of the records."""

def log_names(paths: list[str]) -> list[str]:
    """The names ``fit --each`` gives the logs: the shortest telling path suffixes."""

def expand_logs(pattern: str) -> list[str]:
    """The logs of a folder or glob, as ``fit --each`` finds them."""

def validate(logs: list[str], options: dict[str, Any]) -> str:
    """``greybox validate`` over ``logs`` with the keyword ``options`` (``params`` among
    them): the JSON of ``--json``."""

def track(
    logs: list[str],
    options: dict[str, Any],
) -> list[tuple[str, tuple[float, float, float, Optional[float], Optional[float], Optional[float]], pa.RecordBatch]]:
    """``greybox track`` over ``logs`` with the keyword ``options`` (``pole_pairs`` among
    them): per run its name, final ``(k_e, k_t, r_s, k_e_se, r_s_se, innovation_ratio)``
    (the standard errors ``None`` for the MRAS) and trajectory."""

def simulate(options: dict[str, Any]) -> tuple[pa.RecordBatch, str]:
    """``greybox simulate`` with the keyword ``options``: the log as a batch and the truth
    as JSON."""

def report(
    command: str, sources: list[Any], names: list[str], options: dict[str, Any]
) -> tuple[str, list[str]]:
    """``greybox fluxmap|saturation|standstill|mechanics`` on ``sources`` (paths, or Arrow
    tables named by ``names`` in their places; ``fluxmap``: one map) with the keyword
    ``options``: the JSON report and the codes of the reasons it is not to be trusted."""
