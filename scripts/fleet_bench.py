#!/usr/bin/env python3
"""Fleet throughput: Dask ``fit_fleet`` on a ``LocalCluster`` against ``fit_many`` (threads)
and ``greybox fit --each`` on the same logs; the estimates compared bit for bit.

    python scripts/fleet_bench.py /tmp/fleet-logs [--workers 2] [--repeat 3]

Prints a Markdown table: wall time (the best of ``--repeat``), logs/s, the cluster's start
time, Dask's overhead per task (trivial tasks, and the difference from ``fit_many``), and
whether every estimate equals the command line's to the bit.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time

import pyarrow.csv as pacsv

import greybox
import greybox.dask

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
#: The estimates compared bit for bit (value and standard error).
NUMBERS = ["r_s [Ω]", "l_s [H]", "k_e [V s/rad]", "k_t [N m/A]", "psi_f [V s]", "fit_id [%]", "fit_iq [%]"]


def best(repeat: int, f) -> tuple[float, object]:
    """The shortest wall time [s] of ``repeat`` calls of ``f`` and its last result."""
    times, out = [], None
    for _ in range(repeat):
        t = time.perf_counter()
        out = f()
        times.append(time.perf_counter() - t)
    return min(times), out


def cli_each(binary: str, folder: str, threads: int) -> tuple[float, object]:
    """``greybox fit --each FOLDER -p 4 --summary`` with ``threads`` (RAYON_NUM_THREADS)."""
    with tempfile.TemporaryDirectory() as d:
        env = {**os.environ, "RAYON_NUM_THREADS": str(threads)}
        t = time.perf_counter()
        out = subprocess.run(
            [binary, "fit", "--each", folder, "-p", "4", "--summary", f"{d}/s.csv"], env=env, capture_output=True
        )
        dt = time.perf_counter() - t
        if out.returncode not in (0, 3):
            sys.exit(f"greybox fit --each exited {out.returncode}: {out.stderr.decode()[-2000:]}")
        return dt, pacsv.read_csv(f"{d}/s.csv")


def same_bits(a, b) -> str:
    """Whether the estimates and standard errors of two summaries are equal to the bit."""
    if a.column("log").to_pylist() != b.column("log").to_pylist():
        return "no: the logs differ"
    names = NUMBERS + [n.replace(" [", "_se [") for n in NUMBERS[:5]]
    for name in names:
        if name not in a.column_names or name not in b.column_names:
            return f"no: column {name} missing"
        x, y = a.column(name).to_pylist(), b.column(name).to_pylist()
        bad = [k for k, (u, v) in enumerate(zip(x, y)) if u != v]
        if bad:
            return f"no: {name} differs in {len(bad)} logs (first {a.column('log')[bad[0]]}: {x[bad[0]]!r} vs {y[bad[0]]!r})"
    return f"yes ({len(names)} columns × {a.num_rows} logs)"


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("folder")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--binary", default=os.path.join(ROOT, "target", "release", "greybox"))
    a = p.parse_args()
    from dask.distributed import Client, LocalCluster

    paths = list(greybox._paths(a.folder))
    n = len(paths)
    rows = []

    def row(what, seconds, note=""):
        rows.append((what, seconds, n / seconds if seconds else float("nan"), note))
        print(f"{what}: {seconds:.3f} s", file=sys.stderr)

    t_serial, _ = best(a.repeat, lambda: greybox.fit_many(paths, pole_pairs=4, threads=1))
    row("fit_many, 1 thread", t_serial, f"{1000 * t_serial / n:.1f} ms per log")
    t_many, many = best(a.repeat, lambda: greybox.fit_many(paths, pole_pairs=4, threads=a.workers))
    row(f"fit_many, {a.workers} threads", t_many)
    t_cli, cli = min((cli_each(a.binary, a.folder, a.workers) for _ in range(a.repeat)), key=lambda r: r[0])
    row(f"greybox fit --each, {a.workers} threads", t_cli, f"bit for bit as fit_many: {same_bits(cli, many)}")

    t = time.perf_counter()
    cluster = LocalCluster(n_workers=a.workers, threads_per_worker=1, processes=True, dashboard_address=None)
    client = Client(cluster)
    client.run(lambda: __import__("greybox"))  # the workers import the package once
    start = time.perf_counter() - t
    rows.append((f"LocalCluster(n_workers={a.workers}) start", start, None, "workers up, greybox imported"))
    try:
        t_triv, _ = best(a.repeat, lambda: client.gather(client.map(lambda x: x, range(n), pure=False)))
        rows.append((f"Dask: {n} trivial tasks", t_triv, None, f"{1000 * t_triv / n:.2f} ms per task"))
        for g in (1, 4, 16):
            t_d, fleet = best(a.repeat, lambda g=g: greybox.dask.fit_fleet(paths, client, pole_pairs=4, group_size=g))
            tasks = -(-n // g)
            over = (t_d - t_many) / tasks * 1000
            row(
                f"Dask fit_fleet, group_size {g} ({tasks} tasks)",
                t_d,
                f"bit for bit as --each: {same_bits(fleet, cli)}; {over:+.1f} ms per task vs fit_many",
            )
    finally:
        client.close()
        cluster.close()

    print(f"\n{n} logs from {a.folder}; {os.cpu_count()} cores; best of {a.repeat}\n")
    print("| run | wall [s] | logs/s | note |")
    print("| --- | ---: | ---: | --- |")
    for what, s, rate, note in rows:
        print(f"| {what} | {s:.2f} | {'' if rate is None else f'{rate:.1f}'} | {note} |")
    return 0


if __name__ == "__main__":  # LocalCluster starts worker processes: the guard is needed
    sys.exit(main())
