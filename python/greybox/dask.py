"""A fleet of logs fitted on a Dask cluster: one task per log (or per small group), the
summary records gathered and turned into the table of :func:`greybox.fit_many`.

Dask is imported here only: ``import greybox`` does not need it.

>>> from dask.distributed import Client, LocalCluster
>>> if __name__ == "__main__":  # doctest: +SKIP
...     with LocalCluster(n_workers=2) as cluster, Client(cluster) as client:
...         table = greybox.dask.fit_fleet("runs/", client, pole_pairs=4)
"""

from __future__ import annotations

from typing import Any, Iterable, Optional, Union

import pyarrow as pa

from . import PathLike, _flags, _greybox, _paths, _summary_table

__all__ = ["fit_fleet"]


def _fit_group(paths: list[str], names: list[str], options: dict[str, Any]) -> list[str]:
    """A task: the summary records (JSON) of one group of logs, fitted one at a time."""
    return _greybox.fit_records(paths, names, options, 1)


def fit_fleet(
    logs: Union[PathLike, Iterable[PathLike]],
    client: Any = None,
    *,
    pole_pairs: Union[int, str],
    model: str = "spm",
    group_size: int = 1,
    **options: Any,
) -> pa.Table:
    """Fits each log on its own on a Dask cluster; the table of :func:`greybox.fit_many`.

    ``logs``: a list of paths or a folder or glob; each worker must reach the paths.
    ``client``: a ``dask.distributed.Client`` (default: the current one, else Dask's
    default scheduler). ``group_size``: logs per task (1: a task per log; larger groups cut
    the scheduling overhead of many short logs). Options as for :func:`greybox.fit`. The rows
    come back in the order of the logs, with the columns, names and statuses
    :func:`greybox.fit_many` gives (a log that fails is a ``failed`` row).

    Raises :class:`greybox.OptionError` for invalid options, found before any task is sent.
    """
    import dask

    if group_size < 1:
        raise _greybox.OptionError("invalid option `group_size`: at least 1 log per task")
    paths = _paths(logs)
    names = _greybox.log_names(paths)
    flags = _flags(pole_pairs=pole_pairs, model=model, **options)
    # The options are checked here, before any task: a bad one raises once, not per log.
    _greybox.fit_records([], [], flags, 1)
    groups = [(paths[k : k + group_size], names[k : k + group_size]) for k in range(0, len(paths), group_size)]
    if client is None:
        try:
            from dask.distributed import get_client

            client = get_client()
        except (ImportError, ValueError):
            client = None
    if client is not None:
        futures = client.map(_fit_group, [g[0] for g in groups], [g[1] for g in groups], options=flags, pure=False)
        results = client.gather(futures)
    else:
        tasks = [dask.delayed(_fit_group)(p, n, flags) for p, n in groups]
        results = dask.compute(*tasks)
    return _summary_table([r for group in results for r in group])
