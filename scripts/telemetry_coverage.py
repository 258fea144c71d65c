"""Monte Carlo coverage of `greybox fit` on slow telemetry cut from a log (issue 43).

Per seed: white Gaussian noise added to the currents `id, iq` [A], the voltages `ud, uq`
[V] and the speed `w_m` [rad/s] of every kept row of LOG (a noise-free log with those
columns), every k-th row kept from the first (a host logger's rate), the result fitted with
`BIN fit F -p N --json J -q` (the model chosen automatically, or EXTRA flags). Per
(k, noise scale, parameter): fits, the fraction that exit 3, the coverage of the reported
95 % interval over all fits (exit 3 included), and over the exit-0 fits the coverage, the
mean and the standard deviation of z = (estimate − truth)/standard error, and max |z|.
With --vs OTHER_BIN the same noisy files are fitted by both binaries (a paired comparison).

The noise is that of the rows kept (white noise cut at every k-th row is white noise of
the same σ). Defaults: σ of the shared `servo_spm_moves_idinj_noisy` (currents 0.05 A,
voltages 0.02 V, speed 0.005 rad/s); --sigma sets them (`id=0.03,iq=0.03,ud=1,uq=1,w_m=0`,
issue 43's 1 V + 0.03 A, with --every 1 for the whole log); --scale multiplies all of them.

usage: python3 scripts/telemetry_coverage.py BIN LOG TRUTH SEED0 SEED1 [--every 20,80]
           [--scale 1,0.2] [--sigma id=A,iq=A,ud=V,uq=V,w_m=RAD_S] [--vs OTHER_BIN]
           [-- EXTRA fit flags]
TRUTH: name=value pairs (`r_s=1.2,l_s=0.005,k_e=0.49,n_p=4`, SI units, n_p the pole
pairs), or a truth JSON with the keys of ../shared/data/README.md (Rs_ohm, Ls_H, Ld_H,
Lq_H, Ke_project_Vs_per_rad_mech, np_pole_pairs).
e.g.   python3 scripts/telemetry_coverage.py target/release/greybox \\
           ../shared/data/ipm_moves_idinj.csv.gz ../shared/data/ipm_moves_idinj.json 0 99 -- --model ipm
Needs only the standard library.
"""
import csv, gzip, json, math, os, random, statistics, subprocess, sys, tempfile

KEYS = {"Rs_ohm": "r_s", "Ls_H": "l_s", "Ld_H": "l_d", "Lq_H": "l_q", "Ke_project_Vs_per_rad_mech": "k_e",
        "np_pole_pairs": "n_p"}
SIGMA = {"id": 0.05, "iq": 0.05, "ud": 0.02, "uq": 0.02, "w_m": 0.005}


def options(argv):
    args, extra = (argv[:argv.index("--")], argv[argv.index("--") + 1:]) if "--" in argv else (argv, [])
    if len(args) < 5:
        sys.exit(__doc__)
    opt = {"every": "20,80", "scale": "1,0.2", "sigma": None, "vs": None}
    rest = args[5:]
    for flag, value in zip(rest[::2], rest[1::2]):
        if flag.lstrip("-") not in opt:
            sys.exit(f"unknown option {flag}: --every, --scale, --sigma or --vs")
        opt[flag.lstrip("-")] = value
    return args[:5], opt, extra


def truth_of(arg):
    if arg.endswith(".json"):
        raw = json.load(open(arg))
        return {KEYS[k]: float(v) for k, v in raw.items() if k in KEYS and v is not None}
    return {k: float(v) for k, v in (p.split("=") for p in arg.split(","))}


def read(path):
    with (gzip.open(path, "rt") if path.endswith(".gz") else open(path)) as f:
        rows = list(csv.reader(f))
    header, rows = rows[0], rows[1:]
    missing = [c for c in SIGMA if c not in header]
    if missing:
        sys.exit(f"{path}: no column {', '.join(missing)} (needs {', '.join(SIGMA)})")
    return header, rows


def fit(binary, path, n_p, extra):
    out = path[:-4] + ".json"
    if os.path.exists(out):
        os.remove(out)
    rc = subprocess.run([binary, "fit", path, "-p", str(n_p), "--json", out, "-q", *extra],
                        capture_output=True, text=True).returncode
    if not os.path.exists(out):
        return rc, []
    return rc, json.load(open(out))["parameters"]


def main():
    (binary, log, truth_arg, s0, s1), opt, extra = options(sys.argv[1:])
    truth = truth_of(truth_arg)
    n_p = int(truth.pop("n_p"))
    if opt["sigma"]:
        for pair in opt["sigma"].split(","):
            name, _, value = pair.partition("=")
            if name not in SIGMA:
                sys.exit(f"--sigma {pair}: no noise for column {name!r} (the columns are {', '.join(SIGMA)})")
            try:
                SIGMA[name] = float(value)
            except ValueError:
                sys.exit(f"--sigma {pair}: {value!r} is not a number (e.g. --sigma id=0.03,ud=1)")
    header, rows = read(log)
    cols = {c: header.index(c) for c in SIGMA}
    bins = {"": binary} if opt["vs"] is None else {"A ": binary, "B ": opt["vs"]}
    every = [int(k) for k in opt["every"].split(",")]
    scales = [float(s) for s in opt["scale"].split(",")]
    tmp = tempfile.mkdtemp(prefix="telemetry_coverage_")
    got = {}  # (bin, k, scale, parameter) -> [(exit code, z, interval covers)]
    for seed in range(int(s0), int(s1) + 1):
        for si, scale in enumerate(scales):
            for k in every:
                rng = random.Random(f"{seed}/{si}/{k}")
                path = os.path.join(tmp, f"k{k}.csv")
                with open(path, "w", newline="") as f:
                    w = csv.writer(f)
                    w.writerow(header)
                    for row in rows[::k]:
                        row = list(row)
                        for c, j in cols.items():
                            row[j] = repr(float(row[j]) + rng.gauss(0.0, SIGMA[c] * scale))
                        w.writerow(row)
                for tag, b in bins.items():
                    rc, params = fit(b, path, n_p, extra)
                    for p in params:
                        if p["name"] in truth:
                            t = truth[p["name"]]
                            z = (p["value"] - t) / p["std_error"]
                            lo, hi = p["ci95"]
                            got.setdefault((tag, k, scale, p["name"]), []).append(
                                (rc, z, lo <= t <= hi, abs(p["value"] / t - 1.0)))
    print("| binary | every | noise scale | parameter | fits | exit 3 | coverage (all fits) | coverage (exit 0) | mean z "
          "| sd z | max abs z | max error % (exit 0) |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for (tag, k, scale, name), v in sorted(got.items()):
        z = [z for rc, z, _, _ in v if rc == 0]
        share3 = sum(rc == 3 for rc, _, _, _ in v) / len(v)
        cover_all = sum(c for _, _, c, _ in v) / len(v)
        if z:
            cover = sum(c for rc, _, c, _ in v if rc == 0) / len(z)
            sd = statistics.pstdev(z) if len(z) > 1 else math.nan
            worst = 100.0 * max(e for rc, _, _, e in v if rc == 0)
            stats = f"{cover:.3f} | {statistics.fmean(z):+.2f} | {sd:.2f} | {max(map(abs, z)):.2f} | {worst:.3g}"
        else:
            stats = "– | – | – | – | –"
        print(f"| {tag.strip() or binary} | {k} | {scale:g} | {name} | {len(v)} | {share3:.2f} | {cover_all:.3f} "
              f"| {stats} |")


if __name__ == "__main__":
    main()
