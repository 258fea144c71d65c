#!/usr/bin/env python3
"""Times `greybox fit` from random starts on a shared log (issue 45).

Every parameter of the start is drawn log-uniformly in [0.2x, 5x] of the log's truth file
(the truth only centres the starts); each fit runs as its own process. Prints per start
the wall time, the exit code, the largest relative error of the estimate against the
truth and the iterations, then the median, the largest time and how many starts took more
than 3 times the median. Usage::

    python scripts/random_starts.py BINARY [N] [SHARED_DATA] [LOG POLE_PAIRS MODEL [HOLD]]

BINARY: the greybox binary; N: starts (default 26); SHARED_DATA: the folder of the shared
logs (default ../shared/data beside the repository); LOG POLE_PAIRS MODEL: the log's name
without `.csv.gz`, its pole pairs, `ipm` or `spm`, and the voltage hold (`--hold`, the
fit's automatic choice if not given; default `ipm_moves_idinj 2 ipm stator`, the hold of that
log's generator).
"""

import json
import math
import os
import random
import statistics
import subprocess
import sys
import tempfile
import time


def main() -> None:
    binary = sys.argv[1]
    n = int(sys.argv[2]) if len(sys.argv) > 2 else 26
    here = os.path.dirname(os.path.abspath(__file__))
    data = sys.argv[3] if len(sys.argv) > 3 else os.path.join(here, "..", "..", "shared", "data")
    name, pole_pairs, model, *hold = sys.argv[4:8] if len(sys.argv) > 6 else ("ipm_moves_idinj", "2", "ipm", "stator")
    log = os.path.join(data, name + ".csv.gz")
    t = json.load(open(os.path.join(data, name + ".json")))
    if model == "ipm":
        truth = [t["Rs_ohm"], t["Ld_H"], t["Lq_H"], t["Ke_project_Vs_per_rad_mech"]]
        options = ["--model", "ipm"]
    else:
        truth = [t["Rs_ohm"], t["Ls_H"], t["Ke_project_Vs_per_rad_mech"]]
        options = ["--model", "spm"]
    options += ["--hold", hold[0]] if hold else []
    rng = random.Random(7)
    times = []
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "fit.json")
        for k in range(n):
            start = [v * math.exp(rng.uniform(math.log(0.2), math.log(5.0))) for v in truth]
            cmd = [binary, "fit", log, "-p", pole_pairs, *options, "--start",
                   ",".join(f"{v:.6e}" for v in start), "--json", out, "-q"]
            t0 = time.perf_counter()
            r = subprocess.run(cmd, capture_output=True, text=True)
            dt = time.perf_counter() - t0
            times.append(dt)
            if r.returncode in (0, 3):
                d = json.load(open(out))
                est = [p["value"] for p in d["parameters"][: len(truth)]]
                err = max(abs(e / v - 1.0) for e, v in zip(est, truth))
                iters = d["solver"].get("iterations")
            else:
                err, iters = float("nan"), None
            print(f"{k:3d} {dt:7.3f} s exit {r.returncode} max rel err {err:.2e} iterations {iters}", flush=True)
    med = statistics.median(times)
    slow = sum(x > 3.0 * med for x in times)
    print(f"median {med:.3f} s, max {max(times):.3f} s ({max(times) / med:.2f}x), above 3x the median: {slow}")


if __name__ == "__main__":
    main()
