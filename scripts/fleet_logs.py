#!/usr/bin/env python3
"""A synthetic fleet with known truth: M motors × L logs simulated by ``greybox.simulate``.

Each motor has its own nominal R_s0 [Ω], L_s [H] and psi_f0 [V s] at T_0 = 20 °C (a few %
manufacturing spread around the exp3 servo); each log runs at its own winding temperature
T_w, uniform in [25, 110] °C, with the magnets at T_m = T_w − 15 °C. The simulator applies
the crate's coefficients (MODEL.md §3): R_s = R_s0 (1 + 0.00393 (T_w − T_0)),
psi_f = psi_f0 (1 − 0.0011 (T_m − T_0)).

Two motors are faulty from their 4th log on (log index 3): one demagnetises (psi_f0 −3 %,
``psi_f_factor``), one has a connection fault (R_s +8 % beyond its temperature,
``r_s_factor``). Every log gets a measured winding temperature column ``t_winding`` [°C]:
T_w plus a per-log sensor error (σ = 1 K) plus per-sample noise (σ = 0.5 K). Currents carry
sensor noise (σ = 0.01 A).

Writes ``motorMMM_logLL.parquet`` (or ``.csv.gz``) and ``truth.tsv`` (one row per log,
tab-separated: a ``.csv`` would be read as a log by ``greybox fit --each DIR``) to the
output folder. Usage::

    python scripts/fleet_logs.py /tmp/fleet-logs --motors 40 --logs 6
    python scripts/fleet_logs.py DIR --motors 4 --logs 4 --demagnetised 1 --fault 2
"""

from __future__ import annotations

import argparse
import csv
import gzip
import os
import random
import sys
from concurrent.futures import ThreadPoolExecutor

import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.csv as pacsv
import pyarrow.parquet as pq

import greybox

T0 = 20.0
#: Magnets run this much cooler than the winding [K].
MAGNET_OFFSET = 15.0
#: The faults start at this log (0-based: the 4th log).
FAULT_FROM = 3
#: Spread of a motor's measured temperature: per-log sensor error, per-sample noise [K].
SENSOR_SD, SAMPLE_SD = 1.0, 0.5


def plan(motors: int, logs: int, seed: int, demagnetised: int, fault: int) -> list[dict]:
    """The truth of every log: one dict per (motor, log), in file-name order."""
    rng = random.Random(seed)
    rows = []
    for m in range(motors):
        r_s0 = 1.2 * (1 + rng.uniform(-0.03, 0.03))
        l_s = 5e-3 * (1 + rng.uniform(-0.03, 0.03))
        psi_f0 = 0.1 * (1 + rng.uniform(-0.02, 0.02))
        for k in range(logs):
            t_w = rng.uniform(25.0, 110.0)
            demag = m == demagnetised and k >= FAULT_FROM
            bad = m == fault and k >= FAULT_FROM
            rows.append(
                {
                    "motor": f"motor{m:03d}",
                    "log": k,
                    "seed": seed * 100_000 + m * 100 + k + 1,
                    "r_s0": r_s0,
                    "l_s": l_s,
                    "psi_f0": psi_f0,
                    "t_winding": t_w,
                    "t_magnet": t_w - MAGNET_OFFSET,
                    "t_sensor_error": rng.gauss(0.0, SENSOR_SD),
                    "psi_f_factor": 0.97 if demag else 1.0,
                    "r_s_factor": 1.08 if bad else 1.0,
                    "demagnetised": demag,
                    "r_s_fault": bad,
                }
            )
    return rows


def write_log(row: dict, out: str, fmt: str, scenario: str, duration: float) -> dict:
    """Simulates one log, adds its ``t_winding`` column, writes it; the row with the truth."""
    settings = {
        "motor.r_s": row["r_s0"],
        "motor.l_d": row["l_s"],
        "motor.l_q": row["l_s"],
        "motor.psi_f": row["psi_f0"],
        "thermal.t0": T0,
        "thermal.winding": [[0.0, row["t_winding"]]],
        "thermal.magnet": [[0.0, row["t_magnet"]]],
        "sensors.current_noise": 0.01,
    }
    if row["psi_f_factor"] != 1.0:
        settings["psi_f_factor"] = [[0.0, row["psi_f_factor"]]]
    if row["r_s_factor"] != 1.0:
        settings["r_s_factor"] = [[0.0, row["r_s_factor"]]]
    table, truth = greybox.simulate(scenario, duration=duration, seed=row["seed"], set=settings)
    noise = random.Random(row["seed"])
    base = row["t_winding"] + row["t_sensor_error"]
    temps = pa.array([base + noise.gauss(0.0, SAMPLE_SD) for _ in range(table.num_rows)], pa.float64())
    table = table.append_column("t_winding", temps)
    name = f"{row['motor']}_log{row['log']:02d}.{fmt}"
    path = os.path.join(out, name)
    if fmt == "parquet":
        pq.write_table(table, path)
    else:
        with gzip.open(path, "wb") as f:
            pacsv.write_csv(table, f, pacsv.WriteOptions(quoting_style="none"))
    start = truth["start"]
    k_e = truth["k_e"]
    return {
        **row,
        "path": name,
        "t_winding_measured": pc.mean(temps).as_py(),
        "r_s": start["r_s"],
        "psi_f": start["psi_f"],
        "k_e": k_e,
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("out", help="output folder (created)")
    p.add_argument("--motors", type=int, default=40)
    p.add_argument("--logs", type=int, default=6, help="logs per motor (the faults start at the 4th)")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--demagnetised", type=int, default=7, help="index of the demagnetising motor (-1: none)")
    p.add_argument("--fault", type=int, default=13, help="index of the motor with an R_s fault (-1: none)")
    p.add_argument("--scenario", default="exp3")
    p.add_argument("--duration", type=float, default=2.0, help="length of each log [s]")
    p.add_argument("--format", choices=["parquet", "csv.gz"], default="parquet")
    p.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    a = p.parse_args(argv)
    if a.logs <= FAULT_FROM and (a.demagnetised >= 0 or a.fault >= 0):
        p.error(f"--logs {a.logs}: the faults start at log {FAULT_FROM + 1}; give at least {FAULT_FROM + 1} logs")
    for name, k in (("--demagnetised", a.demagnetised), ("--fault", a.fault)):
        if k >= a.motors:
            p.error(f"{name} {k}: there are only {a.motors} motors (0 … {a.motors - 1})")
    os.makedirs(a.out, exist_ok=True)
    rows = plan(a.motors, a.logs, a.seed, a.demagnetised, a.fault)
    with ThreadPoolExecutor(a.jobs) as pool:
        done = list(pool.map(lambda r: write_log(r, a.out, a.format, a.scenario, a.duration), rows))
    with open(os.path.join(a.out, "truth.tsv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(done[0]), delimiter="\t")
        w.writeheader()
        w.writerows(done)
    print(f"{len(done)} logs ({a.motors} motors × {a.logs}) in {a.out}; truth in {a.out}/truth.tsv", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
