#!/usr/bin/env python3
"""A fleet of logs fitted with Ray Data: ``map_batches`` over the logs' paths, each batch
fitted by :func:`greybox.fit_many` (one thread per Ray task), the rows returned as Arrow.

    pip install 'ray[data]' greybox            # Ray Data's read_parquet also wants aiohttp
    python python/examples/ray_fleet.py /tmp/fleet-logs [--logs 24] [--batch 4] [--cpus 2]

Every Ray worker must reach the paths (a shared file system, or object-store URLs the
logs' readers understand: here local files). The result is the table of ``fit_many``, in
the order of the paths, written to ``--out`` (Parquet) if given; the times are printed.
"""

from __future__ import annotations

import argparse
import glob
import os
import sys
import time

import pyarrow as pa

import greybox


def fit_batch(batch: pa.Table, options: dict) -> pa.Table:
    """A Ray Data batch of paths (column ``path``) → its ``fit_many`` rows (Arrow)."""
    paths = batch.column("path").to_pylist()
    return greybox.fit_many(paths, threads=1, **options)


def log_paths(folder: str) -> list[str]:
    """The Parquet logs of a folder, or the files of a glob, sorted."""
    pattern = os.path.join(folder, "*.parquet") if os.path.isdir(folder) else folder
    return sorted(glob.glob(pattern))


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("folder", help="a folder of Parquet logs, or a glob")
    p.add_argument("--logs", type=int, default=None, help="only the first N logs")
    p.add_argument("--batch", type=int, default=4, help="logs per Ray task")
    p.add_argument("--cpus", type=int, default=2)
    p.add_argument("--pole-pairs", default="4")
    p.add_argument("--out", help="write the table here (Parquet)")
    a = p.parse_args()
    import ray

    paths = log_paths(a.folder)[: a.logs]
    options = {"pole_pairs": a.pole_pairs}
    t = time.perf_counter()
    ray.init(num_cpus=a.cpus, include_dashboard=False, log_to_driver=False)
    started = time.perf_counter() - t

    t = time.perf_counter()
    ds = ray.data.from_items([{"path": x} for x in paths], override_num_blocks=max(1, len(paths) // a.batch))
    fitted = ds.map_batches(fit_batch, fn_kwargs={"options": options}, batch_size=a.batch, batch_format="pyarrow")
    table = pa.concat_tables(ray.get(fitted.to_arrow_refs()))
    # Ray keeps the blocks' order (preserve_order is off only for speed); sort by path anyway.
    table = table.take(pa.compute.sort_indices(table, [("log", "ascending")]))
    ran = time.perf_counter() - t
    ray.shutdown()

    same = table.drop(["time [s]"]).equals(greybox.fit_many(sorted(paths), threads=1, **options).drop(["time [s]"]))
    print(
        f"ray: {len(paths)} logs, init {started:.1f} s, map_batches {ran:.1f} s "
        f"({len(paths) / ran:.1f} logs/s), equal to fit_many: {same}"
    )
    if a.out:
        import pyarrow.parquet as pq

        pq.write_table(table, a.out)
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
