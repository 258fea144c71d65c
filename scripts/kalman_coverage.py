"""Monte Carlo coverage over time of `greybox track --estimator ekf` (issue 46).

Drive-simulator logs of Exp 1 (`greybox simulate --scenario exp1`: a torque step, R_s +20 %
from 9 s to 11 s) with a magnet step psi_f -5 % at 5 s and 0.05 A current noise, one per
seed; the filter starts 10 % low in R_s and 5 % high in K_e. Per seed: the fraction of the
samples after 2 s whose 95 % band covers the truth (R_s, K_e), the settling after the ramp
and the step (within 1 % for good), the delay behind the ramp's middle and the step's half,
the final errors; then their summary over the seeds.

usage: python3 scripts/kalman_coverage.py BIN SEED0 SEED1 [--motor ipm] [extra track flags]
e.g.   python3 scripts/kalman_coverage.py target/release/greybox 1 50
       python3 scripts/kalman_coverage.py target/release/greybox 1 50 --motor ipm
--motor ipm: the drive simulator's interior-magnet motor (salient), tracked with its pole
pairs, --l-s L_d and --l-q L_q from the truth, so the filter steps the exact salient model.
A run the filter's self-check untrusts (exit 3) counts, its JSON is written all the same.
"""
import json, math, os, subprocess, sys, tempfile
binary, s0, s1, *extra = sys.argv[1:]
motor = "spm"
if extra[:2] == ["--motor", "ipm"]:
    motor, extra = "ipm", extra[2:]
def interp(profile, t):
    if not profile: return 1.0
    if t < profile[0][0]: return profile[0][1]
    for (ta, va), (tb, vb) in zip(profile, profile[1:]):
        if ta <= t < tb: return va + (vb - va) * (t - ta) / (tb - ta)
    # after the last breakpoint, or at a step: the last value whose time <= t
    last = [v for (tt, v) in profile if tt <= t]
    return last[-1]
res = []
for seed in range(int(s0), int(s1) + 1):
    log = os.path.join(tempfile.gettempdir(), f"kalman_coverage_{os.getpid()}_{seed}.csv.gz")
    subprocess.run([binary, "simulate", "--scenario", "exp1", "--motor", motor, "--set", "sensors.current_noise=0.05",
                    "--set", "psi_f_factor=[[0,1],[5,1],[5,0.95]]", "--seed", str(seed), "-o", log],
                   check=True, capture_output=True)
    truth = json.load(open(log.replace(".csv.gz", ".truth.json")))
    cfg = truth["config"]; m = cfg["motor"]
    assert not cfg.get("thermal", {}).get("winding"), cfg.get("thermal")
    k_e0 = truth["k_e"]
    machine = ["-p", str(m["n_p"]), "--l-s", str(m["l_d"])] + (["--l-q", str(m["l_q"])] if motor == "ipm" else [])
    out = subprocess.run([binary, "track", log, *machine, "--estimator", "ekf",
                          "--k-e0", str(1.05 * k_e0), "--r-s0", str(0.9 * m["r_s"]), "--json", "-", "--max-points", "10000000", *extra],
                         capture_output=True, text=True)
    if out.returncode not in (0, 3):
        print(seed, out.stderr[-500:]); continue
    tr = json.loads(out.stdout)["trajectory"]
    os.remove(log)
    os.remove(log.replace(".csv.gz", ".truth.json"))
    stats = {}
    for name, base, prof, est, se in [("r_s", m["r_s"], cfg["r_s_factor"], tr["r_s"], tr["r_s_se"]),
                                      ("k_e", k_e0, cfg["psi_f_factor"], tr["k_e"], tr["k_e_se"])]:
        inside = total = 0
        for t, x, s in zip(tr["t"], est, se):
            if t < 2.0: continue
            total += 1
            inside += abs(x - base * interp(prof, t)) <= 1.96 * s
        stats[name] = inside / total
    # lag: after the R_s ramp ends (11 s), first time the estimate is within 1 % of the truth for good
    def settle(est, t, truth_end, t_from):
        last_bad = t_from
        for tt, x in zip(t, est):
            if tt >= t_from and abs(x / truth_end - 1) > 0.01: last_bad = tt
        return last_bad - t_from
    stats["lag_r_s"] = settle(tr["r_s"], tr["t"], 1.2 * m["r_s"], 11.0)
    def cross(est, t, level, t_true, up):
        for tt, x in zip(t, est):
            if tt >= t_true - 1.0 and ((x >= level) if up else (x <= level)): return tt - t_true
        return float("nan")
    # the estimate's delay behind the ramp's middle (1.1 R_s0 at 10 s) and the step's half (5 s)
    stats["delay_r_s"] = cross(tr["r_s"], tr["t"], 1.1 * m["r_s"], 10.0, True)
    stats["delay_k_e"] = cross(tr["k_e"], tr["t"], 0.975 * k_e0, 5.0, False)
    stats["lag_k_e"] = settle(tr["k_e"], tr["t"], 0.95 * k_e0, 5.0)
    stats["final_r_s"] = tr["r_s"][-1] / (1.2 * m["r_s"]) - 1
    stats["final_k_e"] = tr["k_e"][-1] / (0.95 * k_e0) - 1
    print(seed, json.dumps({k: round(v, 4) for k, v in stats.items()}), flush=True)
    res.append(stats)
n = len(res)
for k in ["r_s", "k_e"]:
    print(f"coverage {k}: mean {sum(r[k] for r in res)/n:.3f}, min {min(r[k] for r in res):.3f}")
for k in ["lag_r_s", "lag_k_e", "delay_r_s", "delay_k_e", "final_r_s", "final_k_e"]:
    v = sorted(r[k] for r in res); print(f"{k}: median {v[n//2]:.4f}, max {v[-1]:.4f}, min {v[0]:.4f}")
