#!/usr/bin/env python3
"""A fleet of logs fitted with PySpark (≥ 4.0), two ways, Arrow in and out:

1. ``mapInArrow`` over a DataFrame of the logs' paths: each partition's paths fitted by
   :func:`greybox.fit_many` (one thread per Spark task), the ``fit_many`` rows returned;
2. ``groupBy("log").applyInArrow`` over one DataFrame holding every log's samples (read by
   Spark from the Parquet files, the log's name as a column): each group, sorted by ``t``
   (a shuffle keeps no order), fitted by :func:`greybox.fit` as a table in memory.

    pip install pyspark greybox                # and a Java 17 or 21 runtime
    python python/examples/spark_fleet.py /tmp/fleet-logs [--logs 24] [--cpus 2]

The workers run ``PYSPARK_PYTHON`` (set here to this interpreter): greybox must be
installed there. Every executor must reach the paths (a shared file system). The times
of both and their agreement with ``fit_many`` are printed.
"""

from __future__ import annotations

import argparse
import glob
import os
import sys
import time
from typing import Iterator

import pyarrow as pa

import greybox

#: The parameters the grouped fit returns, with standard errors: SI units (Ω, H, V s/rad).
PARAMETERS = ["r_s", "l_s", "k_e"]
GROUP_SCHEMA = "log string, trusted boolean, " + ", ".join(f"{n} double, {n}_se double" for n in PARAMETERS)


def fit_paths(batches: Iterator[pa.RecordBatch], pole_pairs: str) -> Iterator[pa.RecordBatch]:
    """``mapInArrow``: the paths of a partition (column ``path``) → their ``fit_many`` rows."""
    for batch in batches:
        paths = batch.column("path").to_pylist()
        if paths:
            yield from greybox.fit_many(paths, pole_pairs=pole_pairs, threads=1).to_batches()


def fit_group(table: pa.Table, pole_pairs: str) -> pa.Table:
    """``applyInArrow``: one log's samples (any order, with its ``log`` column) → one row:
    ``log, trusted`` and each parameter with its standard error [SI]."""
    log = table.column("log")[0].as_py()
    samples = table.drop_columns(["log"]).sort_by("t")
    fit = greybox.fit(samples, pole_pairs=pole_pairs, name=log)
    row = {"log": [log], "trusted": [fit.trusted]}
    params = {r["name"]: r for r in fit.parameters.to_pylist()}
    for n in PARAMETERS:
        row[n], row[n + "_se"] = [params[n]["value"]], [params[n]["std_error"]]
    return pa.table(row)


def log_paths(folder: str) -> list[str]:
    """The Parquet logs of a folder, or the files of a glob, sorted."""
    pattern = os.path.join(folder, "*.parquet") if os.path.isdir(folder) else folder
    return sorted(glob.glob(pattern))


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("folder", help="a folder or glob of Parquet logs")
    p.add_argument("--logs", type=int, default=None, help="only the first N logs")
    p.add_argument("--batch", type=int, default=4, help="paths per partition (mapInArrow)")
    p.add_argument("--cpus", type=int, default=2)
    p.add_argument("--pole-pairs", default="4")
    a = p.parse_args()
    os.environ.setdefault("PYSPARK_PYTHON", sys.executable)
    from pyspark.sql import SparkSession
    from pyspark.sql import functions as F
    from pyspark.sql.pandas.types import from_arrow_schema

    paths = log_paths(a.folder)[: a.logs]
    pp = a.pole_pairs
    t = time.perf_counter()
    spark = (
        SparkSession.builder.master(f"local[{a.cpus}]")
        .config("spark.ui.enabled", "false")
        .config("spark.sql.shuffle.partitions", str(a.cpus * 2))
        .getOrCreate()
    )
    spark.sparkContext.setLogLevel("ERROR")
    started = time.perf_counter() - t
    reference = greybox.fit_many(paths, pole_pairs=pp, threads=1)

    # 1. mapInArrow over paths; the schema is fit_many's (the same options give the same columns).
    t = time.perf_counter()
    df = spark.createDataFrame([(x,) for x in paths], "path string").repartition(max(1, len(paths) // a.batch))
    fitted = df.mapInArrow(lambda it: fit_paths(it, pp), from_arrow_schema(reference.schema))
    table = fitted.toArrow().sort_by("log")
    t_map = time.perf_counter() - t
    same_map = table.drop_columns(["time [s]"]).equals(reference.drop_columns(["time [s]"]))

    # 2. applyInArrow over every sample, grouped by log.
    t = time.perf_counter()
    samples = spark.read.parquet(*paths).withColumn("log", F.input_file_name())
    rows = samples.groupBy("log").applyInArrow(lambda tb: fit_group(tb, pp), GROUP_SCHEMA).toArrow()
    t_group = time.perf_counter() - t
    by_name = {os.path.basename(r["log"]): r for r in rows.to_pylist()}
    want = {os.path.basename(r["log"]): r for r in reference.to_pylist()}
    same_group = by_name.keys() == want.keys() and all(
        by_name[k][n] == want[k][f"{n} {u}"] for k in want for n, u in zip(PARAMETERS, ["[Ω]", "[H]", "[V s/rad]"])
    )
    spark.stop()
    print(
        f"spark local[{a.cpus}]: {len(paths)} logs, start {started:.1f} s; mapInArrow {t_map:.1f} s "
        f"(equal to fit_many: {same_map}); applyInArrow {t_group:.1f} s (estimates equal to fit_many: {same_group})"
    )
    return 0 if same_map and same_group else 1


if __name__ == "__main__":
    sys.exit(main())
