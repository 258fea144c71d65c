#!/usr/bin/env python3
"""greybox versus scipy.optimize.least_squares(method='lm') on the same surface-magnet fit.

Optional: nothing in the Rust build or tests needs this script (Python 3, numpy, scipy;
numba is used when importable, never required).

What it measures
----------------
1. `greybox fit LOG -p N --hold H --json OUT -q`, run as a subprocess (best wall time of
   --repeat runs, default 3): the whole command line end to end -- read the (gzip) CSV,
   least-squares start, setup checks, prediction-error fit, statistics, JSON report.
   greybox's own `timing.fit_s` (fit_pmsm without the CSV read) is printed beside it, and
   `timing.solve_s`, its solver's iterations from the start alone (the counterpart of
   scipy's least_squares without the preparation).
2. The same output-error fit in scipy: surface-magnet model, parameters (r_s, l_s, k_e)
   plus the initial current x0 = (x0_id, x0_iq) as free parameters (greybox's default
   `estimate_x0`), residuals y_k - yhat_k for k = 0..N-1 on i_d and i_q, unit weights,
   solved by `scipy.optimize.least_squares(method='lm')` (MINPACK lmder) with the
   analytic Jacobian (forward sensitivities), from the **same start**: the least-squares
   start that greybox reports (`parameters[].start`, `initial_states[].start` of its
   JSON), parameters scaled by that start (greybox's `nominal` scaling). Timed: best of
   --repeat runs of [θ-independent preparation + least_squares]; the CSV read is timed
   apart (numpy.loadtxt) and not included. The numba kernel is compiled before timing.
   The script also reproduces greybox's linear least-squares start in numpy and prints
   its relative difference to greybox's (a check, not used for the fit).

The model is greybox's exact sampled-data step (MODEL.md §4, src/pmsm/model/spm.rs,
src/pmsm/model/interval/dq.rs), with i = i_d + j i_q, interval-mean speed w_m = (w[k]+w[k+1])/2,
w_e = n_p w_m, phi = w_e h, rot = e^{-j phi}, e = sqrt(2/3) k_e w_m,
d = e^{-r h/l}, a = rot d, z = r + j w_e l, b = (1 - a)/z:

    dq hold:      i[k+1] = a i[k] + b (u[k] - j e)
    stator hold:  i[k+1] = a i[k] + u0 rot (1 - d)/r - b j e,  u0 = u[k] j phi/(1 - e^{-j phi})

Two implementations of the recursion (with sensitivities):
* `numba`: a compiled loop, the step exactly as greybox writes it (one pass gives the
  residuals; one more with the sensitivities gives the Jacobian).
* `lfilter` (numpy/scipy only): the rotation is data-only and the decay parameter-only,
  so with the accumulated angle R_k = e^{-j sum_{m<k} phi_m} (long-double cumsum) the
  derotated state w = i / R_k obeys w[k+1] = d w[k] + f_k / R_{k+1}: a constant real
  pole, run by scipy.signal.lfilter in C (stable: no growing exponentials); the three
  parameter sensitivities are one 3-row lfilter call, the x0 sensitivity is d^k R_k.

Usage
-----
    python3 benches/compare_scipy.py LOG.csv.gz -p 4 [--hold stator|dq] [--repeat 3]
        [--greybox PATH] [--backend auto|numba|lfilter] [--truth JSON]

Defaults: hold stator; greybox = $GREYBOX, else target/release/greybox of this repository,
else `greybox` on PATH. The truth is read, when present, from the JSON beside the log
(the shared data's or `greybox simulate`'s) and printed for reference.
"""

import argparse
import gzip
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np
from scipy.optimize import least_squares
from scipy.signal import lfilter

SQRT_2_3 = 0.816_496_580_927_726  # as src/pmsm/model/interval/dq.rs
NAMES = ("r_s", "l_s", "k_e")

try:
    import numba

    HAVE_NUMBA = True
except ImportError:  # pragma: no cover
    HAVE_NUMBA = False


# ----------------------------------------------------------------------------- data
def read_log(path):
    """Columns t, ud, uq, id, iq, w_m of a CSV (gzip when the name ends in .gz)."""
    opener = gzip.open if path.endswith(".gz") else open
    with opener(path, "rt") as f:
        header = f.readline().strip().split(",")
        cols = [header.index(c) for c in ("t", "ud", "uq", "id", "iq", "w_m")]
        a = np.loadtxt(f, delimiter=",", usecols=cols, ndmin=2)
    t, ud, uq, i_d, i_q, w_m = (np.ascontiguousarray(a[:, j]) for j in range(6))
    return dict(t=t, u=ud + 1j * uq, i=i_d + 1j * i_q, w_m=w_m, h=(t[-1] - t[0]) / (len(t) - 1))


def prepare(log, n_p, hold):
    """The θ-independent per-interval data (k = 0..N-2), vectorised."""
    h, w = log["h"], log["w_m"]
    wm = 0.5 * (w[:-1] + w[1:])
    we = n_p * wm
    phi = we * h
    rot = np.cos(phi) - 1j * np.sin(phi)
    vers = 2.0 * np.sin(0.5 * phi) ** 2
    u = log["u"][:-1]
    if hold == "stator":
        # u0 = u j phi / (1 - e^{-j phi}), 1 - e^{-j phi} = vers + j sin phi; series near 0.
        small = np.abs(phi) < 1e-8
        denom = np.where(small, 1.0, vers + 1j * np.sin(phi))
        factor = np.where(small, 1.0 - phi * phi / 12.0 + 0.5j * phi, 1j * phi / denom)
        uterm = u * factor * rot
    else:
        uterm = u.copy()
    p = dict(h=h, we=we, emf=SQRT_2_3 * wm, rot=rot, vers=vers, u=uterm, y=log["i"],
             stator=hold == "stator")
    return p


def prepare_lfilter(p):
    """Accumulated rotation R_k (k = 0..N-1) for the lfilter backend."""
    theta = np.concatenate(([0.0], np.cumsum(np.asarray(p["we"] * p["h"], dtype=np.longdouble))))
    theta = theta - np.round(theta / (2 * np.pi)) * (2 * np.longdouble(np.pi))
    theta = theta.astype(np.float64)
    p["R"] = np.cos(theta) - 1j * np.sin(theta)
    p["Rinv_next"] = np.conj(p["R"][1:])
    p["k"] = np.arange(len(theta), dtype=np.float64)
    return p


def ls_start(log, n_p):
    """greybox's linear least-squares start (src/pmsm/linear.rs), unweighted, unfiltered."""
    h, i, w, u = log["h"], log["i"], log["w_m"], log["u"][:-1]
    im, di, wm = 0.5 * (i[:-1] + i[1:]), (i[1:] - i[:-1]) / h, 0.5 * (log["w_m"][:-1] + w[1:])
    we = n_p * wm
    n = len(im)
    phi = np.empty((2 * n, 3))
    phi[0::2] = np.column_stack((im.real, di.real - we * im.imag, np.zeros(n)))
    phi[1::2] = np.column_stack((im.imag, di.imag + we * im.real, SQRT_2_3 * wm))
    y = np.empty(2 * n)
    y[0::2], y[1::2] = u.real, u.imag
    scale = np.linalg.norm(phi, axis=0)
    theta = np.linalg.lstsq(phi / scale, y, rcond=None)[0] / scale
    return theta


# ----------------------------------------------------------------------- coefficients
def coeffs(r, l, h):
    x = r * h / l
    d = np.exp(-x)
    omd = -np.expm1(-x)
    g = omd / r
    return d, omd, g, ((h / l) * d - g) / r, -(h / l) * (d / l)


# --------------------------------------------------------------------- numba backend
if HAVE_NUMBA:

    @numba.njit(cache=False, fastmath=False)
    def _nb_pass(r, l, ke, x0, h, we, emf, rot, vers, u, stator, y, res, jac):
        """One pass; res (2N) and, if jac.shape[0] > 0, jac (2N x 5), residual = y - yhat."""
        n = y.shape[0]
        sens = jac.shape[0] > 0
        x = r * h / l
        d = np.exp(-x)
        omd = -np.expm1(-x)
        g = omd / r
        g_r = ((h / l) * d - g) / r
        g_l = -(h / l) * (d / l)
        hl = h / l
        i = x0
        s_r = 0j
        s_l = 0j
        s_k = 0j
        s_x = 1.0 + 0j
        res[0] = y[0].real - i.real
        res[n] = y[0].imag - i.imag
        if sens:
            jac[0, 3] = -1.0
            jac[n, 4] = -1.0
        for k in range(n - 1):
            w = we[k]
            rk = rot[k]
            a = rk * d
            z = complex(r, w * l)
            b = complex(omd * rk.real + vers[k], -d * rk.imag) / z
            je = complex(0.0, ke * emf[k])
            uk = u[k]
            if stator:
                forced = uk * g - b * je
            else:
                forced = b * (uk - je)
            if sens:
                a_r = a * (-hl)
                a_l = a * (r * hl / l)
                b_r = (a * hl - b) / z
                b_l = (a * (-r * hl / l) - b * complex(0.0, w)) / z
                if stator:
                    f_r = uk * g_r - b_r * je
                    f_l = uk * g_l - b_l * je
                else:
                    f_r = b_r * (uk - je)
                    f_l = b_l * (uk - je)
                s_r = a * s_r + a_r * i + f_r
                s_l = a * s_l + a_l * i + f_l
                s_k = a * s_k - b * complex(0.0, emf[k])
                s_x = a * s_x
                m = k + 1
                jac[m, 0] = -s_r.real
                jac[m + n, 0] = -s_r.imag
                jac[m, 1] = -s_l.real
                jac[m + n, 1] = -s_l.imag
                jac[m, 2] = -s_k.real
                jac[m + n, 2] = -s_k.imag
                jac[m, 3] = -s_x.real
                jac[m + n, 3] = -s_x.imag
                jac[m, 4] = s_x.imag  # d/dx0_iq: j s_x
                jac[m + n, 4] = -s_x.real
            i = a * i + forced
            res[k + 1] = y[k + 1].real - i.real
            res[k + 1 + n] = y[k + 1].imag - i.imag


class Model:
    """Residuals and Jacobian in scaled parameters q = (θ/θ_start, x0) with a θ cache."""

    def __init__(self, p, theta0, backend):
        self.p, self.s, self.backend = p, np.array(list(np.abs(theta0)) + [1.0, 1.0]), backend
        self.n = len(p["y"])
        self._key, self._state = None, None
        if backend == "lfilter":
            prepare_lfilter(p)

    def unpack(self, q):
        v = q * self.s
        return v[0], v[1], v[2], complex(v[3], v[4])

    # numba --------------------------------------------------------------------
    def _nb(self, q, with_jac):
        p = self.p
        r, l, ke, x0 = self.unpack(q)
        res = np.empty(2 * self.n)
        jac = np.empty((2 * self.n, 5)) if with_jac else np.empty((0, 5))
        _nb_pass(r, l, ke, x0, p["h"], p["we"], p["emf"], p["rot"], p["vers"], p["u"],
                 p["stator"], p["y"], res, jac)
        return res, jac

    # lfilter ------------------------------------------------------------------
    def _lf_state(self, q):
        key = q.tobytes()
        if key == self._key:
            return self._state
        p = self.p
        r, l, ke, x0 = self.unpack(q)
        d, omd, g, g_r, g_l = coeffs(r, l, p["h"])
        rot, we = p["rot"], p["we"]
        z = r + 1j * we * l
        b = (omd * rot.real + p["vers"] - 1j * d * rot.imag) / z
        je = 1j * ke * p["emf"]
        forced = p["u"] * g - b * je if p["stator"] else b * (p["u"] - je)
        c = np.empty(self.n, dtype=complex)
        c[0] = x0
        c[1:] = forced * p["Rinv_next"]
        wv = lfilter([1.0], [1.0, -d], c)
        self._key, self._state = key, (r, l, ke, d, g_r, g_l, z, b, je, wv)
        return self._state

    def _lf_res(self, q):
        wv = self._lf_state(q)[-1]
        yhat = wv * self.p["R"]
        e = self.p["y"] - yhat
        return np.concatenate((e.real, e.imag))

    def _lf_jac(self, q):
        p = self.p
        r, l, ke, d, g_r, g_l, z, b, je, wv = self._lf_state(q)
        h, we, emf, rinv = p["h"], p["we"], p["emf"], p["Rinv_next"]
        a_over = (h / l) * d  # a_r i[k] / R_{k+1} = -(h/l) d w[k]; a_l: + r h/l^2 d w[k]
        a = p["rot"] * d
        b_r = (a * (h / l) - b) / z
        b_l = (a * (-r * h / l / l) - b * (1j * we)) / z
        if p["stator"]:
            f_r, f_l = p["u"] * g_r - b_r * je, p["u"] * g_l - b_l * je
        else:
            f_r, f_l = b_r * (p["u"] - je), b_l * (p["u"] - je)
        c = np.zeros((3, self.n), dtype=complex)
        c[0, 1:] = -a_over * wv[:-1] + f_r * rinv
        c[1, 1:] = (r / l) * a_over * wv[:-1] + f_l * rinv
        c[2, 1:] = (-1j * emf) * b * rinv
        sig = lfilter([1.0], [1.0, -d], c, axis=1) * p["R"]
        dx = np.power(d, p["k"]) * p["R"]
        jac = np.empty((2 * self.n, 5))
        for j in range(3):
            jac[: self.n, j], jac[self.n:, j] = -sig[j].real, -sig[j].imag
        jac[: self.n, 3], jac[self.n:, 3] = -dx.real, -dx.imag
        jac[: self.n, 4], jac[self.n:, 4] = dx.imag, -dx.real
        return jac

    # least_squares interface (scaled) -------------------------------------------
    def fun(self, q):
        if self.backend == "numba":
            return self._nb(q, False)[0]
        return self._lf_res(q)

    def jac(self, q):
        j = self._nb(q, True)[1] if self.backend == "numba" else self._lf_jac(q)
        return j * self.s


def scipy_fit(log, n_p, hold, theta0, x0, backend):
    t0 = time.perf_counter()
    p = prepare(log, n_p, hold)
    m = Model(p, theta0, backend)
    t_prep = time.perf_counter() - t0
    q0 = np.array([np.sign(theta0[0]), np.sign(theta0[1]), np.sign(theta0[2]), x0.real, x0.imag])
    t1 = time.perf_counter()
    sol = least_squares(m.fun, q0, jac=m.jac, method="lm", ftol=1e-12, xtol=1e-10, gtol=1e-10)
    t_ls = time.perf_counter() - t1
    v = sol.x * m.s
    return v, sol, t_prep, t_ls


# --------------------------------------------------------------------------- greybox
def find_greybox(arg):
    if arg:
        return arg
    if os.environ.get("GREYBOX"):
        return os.environ["GREYBOX"]
    here = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "target", "release", "greybox")
    if os.path.exists(here):
        return os.path.normpath(here)
    return shutil.which("greybox") or sys.exit("greybox binary not found (--greybox PATH)")


def run_greybox(exe, log, n_p, hold, repeat):
    out = os.path.join(tempfile.mkdtemp(prefix="cmp-scipy-"), "fit.json")
    cmd = [exe, "fit", log, "-p", str(n_p), "--hold", hold, "--json", out, "-q"]
    best, reports = float("inf"), []
    for _ in range(repeat):
        t0 = time.perf_counter()
        rc = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE).returncode
        best = min(best, time.perf_counter() - t0)
        if rc not in (0, 3):
            sys.exit(f"{' '.join(cmd)} failed with exit code {rc}")
        with open(out) as f:
            reports.append(json.load(f))
    return cmd, rc, best, reports


def truth_of(log_path, explicit):
    path = explicit or (log_path[:-7] if log_path.endswith(".csv.gz") else log_path[:-4]) + ".json"
    try:
        with open(path) as f:
            t = json.load(f)
    except (OSError, ValueError):
        return None
    if "Rs_ohm" in t:
        return [t["Rs_ohm"], t.get("Ls_H"), t["Ke_project_Vs_per_rad_mech"]]
    if "start" in t and "k_e" in t:
        return [t["start"]["r_s"], t["start"]["l_d"], t["k_e"]]
    return None


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("log")
    ap.add_argument("-p", "--pole-pairs", type=int, required=True)
    ap.add_argument("--hold", choices=("stator", "dq"), default="stator")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--greybox")
    ap.add_argument("--backend", choices=("auto", "numba", "lfilter"), default="auto")
    ap.add_argument("--truth", help="truth JSON (default: beside the log)")
    a = ap.parse_args()
    backend = ("numba" if HAVE_NUMBA else "lfilter") if a.backend == "auto" else a.backend
    if backend == "numba" and not HAVE_NUMBA:
        sys.exit("numba is not installed (use --backend lfilter)")

    exe = find_greybox(a.greybox)
    cmd, rc, t_gb, reports = run_greybox(exe, a.log, a.pole_pairs, a.hold, a.repeat)
    rep = reports[0]
    gb = {p["name"]: p for p in rep["parameters"]}
    theta0 = np.array([gb[n]["start"] for n in NAMES])
    x0_start = complex(*(s["start"] for s in rep["initial_states"]))
    gb_theta = np.array([gb[n]["value"] for n in NAMES])
    gb_x0 = [s["value"] for s in rep["initial_states"]]
    gb_fit_s = min(r["timing"]["fit_s"] for r in reports)
    gb_read_s = min(r["timing"]["read_s"] for r in reports)
    # The solver's iterations alone (reports from 2026-12-01 on): the counterpart of scipy's
    # least_squares from the same start.
    solves = [r["timing"].get("solve_s") for r in reports]
    gb_solve_s = min(solves) if all(s is not None for s in solves) else None

    t0 = time.perf_counter()
    log = read_log(a.log)
    t_read = time.perf_counter() - t0
    n = len(log["t"])
    ls = ls_start(log, a.pole_pairs)

    if backend == "numba":  # compile outside the timing
        small = {k: (v[:64] if isinstance(v, np.ndarray) else v) for k, v in log.items()}
        scipy_fit(small, a.pole_pairs, a.hold, theta0, x0_start, backend)
    t_sp, t_ls, res = float("inf"), float("inf"), None
    for _ in range(a.repeat):
        t0 = time.perf_counter()
        res = scipy_fit(log, a.pole_pairs, a.hold, theta0, x0_start, backend)
        t_sp = min(t_sp, time.perf_counter() - t0)
        t_ls = min(t_ls, res[3])
    v, sol, t_prep, _ = res
    rms = np.sqrt(np.mean(sol.fun.reshape(2, -1) ** 2, axis=1))

    truth = truth_of(a.log, a.truth)
    print(f"log {a.log}: N = {n} samples, h = {log['h']:.6g} s, n_p = {a.pole_pairs}, hold {a.hold}")
    print(f"greybox: {' '.join(cmd)}  (exit {rc}; {rep['solver']['iterations']} iterations, "
          f"{rep['solver']['evaluations']} evaluations, {rep['solver']['termination']})")
    print(f"scipy:   least_squares(method='lm', analytic jac, backend {backend}; status {sol.status}, "
          f"nfev {sol.nfev}, njev {sol.njev}: {sol.message})")
    print("start (greybox LS, used by both); numpy LS reproduction rel. diff: "
          + ", ".join(f"{nm} {t:.9e} ({l / t - 1:+.1e})" for nm, t, l in zip(NAMES, theta0, ls)))
    print(f"{'param':<7}{'greybox':>23}{'scipy':>23}{'rel diff':>11}" + (f"{'truth':>14}" if truth else ""))
    for j, nm in enumerate(NAMES):
        line = f"{nm:<7}{gb_theta[j]:>23.15e}{v[j]:>23.15e}{v[j] / gb_theta[j] - 1:>11.1e}"
        if truth and truth[j] is not None:
            line += f"{truth[j]:>14.7g}"
        print(line)
    for j, nm in enumerate(("x0_id", "x0_iq")):
        print(f"{nm:<7}{gb_x0[j]:>23.15e}{v[3 + j]:>23.15e}{v[3 + j] - gb_x0[j]:>11.1e} (abs, A)")
    print(f"rms residual id, iq [A]: greybox {rep['fit']['rms_residual'][0]:.6e}, "
          f"{rep['fit']['rms_residual'][1]:.6e}; scipy {rms[0]:.6e}, {rms[1]:.6e}")
    print(f"time, best of {a.repeat}: greybox fit end to end {t_gb:.3f} s (its own read_s {gb_read_s:.3f} s, "
          f"fit_s {gb_fit_s:.3f} s); scipy prepare + least_squares {t_sp:.3f} s (last run: prepare "
          f"{t_prep:.3f} s; CSV read by numpy {t_read:.3f} s, not included)")
    print(f"ratio scipy fit / greybox end to end = {t_sp / t_gb:.2f}; "
          f"scipy fit / greybox fit_s = {t_sp / gb_fit_s:.2f}")
    if gb_solve_s is not None:
        print(f"the solvers alone from the same start, best of {a.repeat}: greybox solve_s {gb_solve_s:.4f} s, "
              f"scipy least_squares {t_ls:.4f} s; ratio scipy / greybox = {t_ls / gb_solve_s:.1f}")


if __name__ == "__main__":
    main()
