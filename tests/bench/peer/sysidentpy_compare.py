#!/usr/bin/env python3
"""Term selection and run time: SysIdentPy's FROLS beside inertia's ERR ranking and selection
engine, on the same candidate matrix and data.

SysIdentPy is not vendored: fetch it (github wilsonrljr/sysidentpy), extract a work tree, and
give its path. Needs Debian's python3-numpy, python3-scipy, python3-matplotlib.

  python3 tests/bench/peer/sysidentpy_compare.py --sysidentpy /tmp/sysidentpy \\
      --tool build/bench/peer_frols_compare [--seeds 3]

For every model and seed: data from a known sparse polynomial NARX model with white noise;
SysIdentPy builds its candidate matrix (Polynomial basis, degree 2, the model's ylag/xlag); that
exact matrix and target go to our tool through a raw float64 file. Two comparisons:
  fixed   - FROLS with n_terms = the true count (SysIdentPy's error_reduction_ratio + least
            squares) against our ERR ranking stopped at the same count + least squares;
  auto    - SysIdentPy choosing the length by AIC (information_criterion, FROLS, least squares)
            against our whole selection (ERR ranking, Bonferroni t-tests, AIC, residual test).
Times exclude data generation and matrix building on both sides (SysIdentPy: its selection and
estimation calls on the matrix; ours: inside the tool). Fixed: the median of 5 runs on both
sides. Auto: one SysIdentPy run (up to 25 s each at p = 78) against our median of 5.
"""
import argparse
import os
import subprocess
import sys
import tempfile
import time

import numpy as np


def parse_args():
    a = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    a.add_argument("--sysidentpy", default=os.environ.get("SYSIDENTPY_DIR"), help="SysIdentPy work tree")
    a.add_argument("--tool", default="build/bench/peer_frols_compare", help="our executable")
    a.add_argument("--seeds", type=int, default=3)
    a.add_argument("--keep", help="keep the problem files (model-N-seed.bin) in this directory")
    args = a.parse_args()
    if not args.sysidentpy or not os.path.isdir(os.path.join(args.sysidentpy, "sysidentpy")):
        sys.exit("sysidentpy_compare: give --sysidentpy DIR (a SysIdentPy work tree holding sysidentpy/); "
                 "it is fetched for the comparison, never vendored")
    if not os.access(args.tool, os.X_OK):
        sys.exit(f"sysidentpy_compare: {args.tool} not built (cmake --build BUILD --target peer_frols_compare)")
    return args


# Each model: inputs, lags SysIdentPy's basis uses, and the truth as (coefficient, factors) with
# factors (signal, lag): signal "y" or input index. simulate() runs the recursion.
MODELS = [
    dict(name="book-narx", n_inputs=1, ylag=2, xlag=2, samples=10_000, noise=0.1,
         truth=[(0.2, [("y", 1)]), (0.1, [("y", 1), (0, 1)]), (0.9, [(0, 2)])]),
    dict(name="book-narx", n_inputs=1, ylag=2, xlag=2, samples=100_000, noise=0.1,
         truth=[(0.2, [("y", 1)]), (0.1, [("y", 1), (0, 1)]), (0.9, [(0, 2)])]),
    dict(name="accel-3in", n_inputs=3, ylag=1, xlag=[[1, 2], [1, 2], [1, 2]], samples=100_000, noise=0.01,
         truth=[(0.004, []), (0.87, [(0, 1)]), (0.02, [(0, 1), (0, 1)]), (0.01, [(0, 1), (1, 1)]),
                (-0.03, [(0, 2)]), (0.015, [(1, 1), (2, 1)])]),
    dict(name="accel-3in-r3", n_inputs=3, ylag=2, xlag=[[1, 2, 3], [1, 2, 3], [1, 2, 3]], samples=100_000,
         noise=0.01,
         truth=[(0.87, [(0, 1)]), (0.02, [(0, 1), (0, 1)]), (0.01, [(0, 1), (1, 1)]), (-0.03, [(0, 3)]),
                (0.1, [("y", 2)])]),
]


def simulate(m, rng):
    # A 100-sample run-in is simulated and dropped, so every row the regressions see (SysIdentPy
    # starts at its max lag) follows the model; rows before the recursion starts would be outliers
    # of up to ~90 noise sd, and the t-tests at N = 1e5 would fit terms to them.
    run_in = 100
    n = m["samples"] + run_in
    x = rng.uniform(-1.0, 1.0, size=(n, m["n_inputs"]))
    e = rng.normal(0.0, m["noise"], size=n)
    y = np.zeros(n)
    start = 4
    for k in range(start, n):
        v = e[k]
        for c, factors in m["truth"]:
            t = c
            for s, lag in factors:
                t *= y[k - lag] if s == "y" else x[k - lag, s]
            v += t
        y[k] = v
    return x[run_in:], y[run_in:]


def true_columns(m, x, y, max_lag, reg):
    """Indices of the candidate matrix's columns that equal the true terms (rows k >= max_lag)."""
    rows = slice(max_lag, len(y))
    found = []
    for _, factors in m["truth"]:
        col = np.ones(len(y) - max_lag)
        for s, lag in factors:
            sig = y if s == "y" else x[:, s]
            col = col * sig[max_lag - lag:len(y) - lag]
        match = [j for j in range(reg.shape[1]) if np.allclose(reg[:, j], col, rtol=1e-12, atol=1e-12)]
        if len(match) != 1:
            sys.exit(f"sysidentpy_compare: true term {factors} matches {len(match)} candidate columns")
        found.append(match[0])
    return sorted(found)


def main():
    args = parse_args()
    sys.path.insert(0, args.sysidentpy)
    from sysidentpy.basis_function import Polynomial
    from sysidentpy.model_structure_selection import FROLS
    from sysidentpy.model_structure_selection.ofr_base import get_min_info_value
    from sysidentpy.parameter_estimation import LeastSquares
    from sysidentpy.utils.information_matrix import build_lagged_matrix

    header = (f"{'model':<13} {'N':>7} {'p':>3} {'mode':<5} {'SysIdentPy':>10} {'ours':>6} "
              f"{'t SysIdentPy':>12} {'t ours':>9} {'ratio':>7}  terms (true | SysIdentPy | ours)")
    print(header)
    print("-" * len(header))
    totals = {"fixed": [0, 0, 0], "auto": [0, 0, 0]}
    ratios = {"fixed": [], "auto": []}
    for m in MODELS:
        for seed in range(args.seeds):
            rng = np.random.default_rng(1000 + seed)
            x, y = simulate(m, rng)
            K = len(m["truth"])
            ycol = y.reshape(-1, 1)

            def frols(**kw):
                return FROLS(ylag=m["ylag"], xlag=m["xlag"], basis_function=Polynomial(degree=2),
                             estimator=LeastSquares(), model_type="NARMAX", **kw)

            fixed = frols(order_selection=False, n_terms=K)
            lagged = build_lagged_matrix(x, ycol, fixed.xlag, fixed.ylag, "NARMAX")
            reg = fixed.basis_function.fit(lagged, fixed.max_lag, fixed.ylag, fixed.xlag, "NARMAX",
                                           predefined_regressors=None)
            reg = np.asarray(reg, dtype=float)
            p = reg.shape[1]
            truth = true_columns(m, x, y, fixed.max_lag, reg)

            times = []
            for _ in range(5):  # the median of 5, as on our side: no first-call penalty for either
                t0 = time.perf_counter()
                out = fixed.run_mss_algorithm(reg, ycol, K)
                _, piv, psi, target = fixed._unpack_mss_output(out, ycol)
                fixed.estimator.optimize(psi, target)
                times.append(time.perf_counter() - t0)
            t_fixed = sorted(times)[2]
            s_fixed = sorted(int(j) for j in np.asarray(piv).reshape(-1)[:K])

            auto = frols(order_selection=True, n_info_values=min(p, 3 * K + 5), info_criteria="aic")
            t0 = time.perf_counter()
            info = auto.information_criterion(reg, ycol)
            length = get_min_info_value(info)
            out = auto.run_mss_algorithm(reg, ycol, length)
            _, piv, psi, target = auto._unpack_mss_output(out, ycol)
            auto.estimator.optimize(psi, target)
            t_auto = time.perf_counter() - t0
            s_auto = sorted(int(j) for j in np.asarray(piv).reshape(-1)[:length])

            if args.keep:
                os.makedirs(args.keep, exist_ok=True)
                f = open(os.path.join(args.keep, f"{m['name']}-{m['samples']}-{seed}.bin"), "wb")
            else:
                f = tempfile.NamedTemporaryFile(suffix=".bin", delete=False)
            with f:
                np.array([reg.shape[0], p], dtype="<i8").tofile(f)
                np.ascontiguousarray(reg.T).astype("<f8").tofile(f)  # column after column (tofile writes C order)
                np.asarray(ycol[fixed.max_lag:, 0], dtype="<f8").tofile(f)
                path = f.name
            try:
                res = subprocess.run([args.tool, path, str(K), "5"], check=True, capture_output=True, text=True)
            finally:
                if not args.keep:
                    os.unlink(path)
            ours = {}
            for line in res.stdout.splitlines():
                method, *fields = line.split()
                kv = dict(fl.split("=", 1) for fl in fields)
                ours[method] = (sorted(int(c) for c in kv["columns"].split(",") if c), float(kv["seconds"]))

            for mode, theirs, t_theirs in (("fixed", s_fixed, t_fixed), ("auto", s_auto, t_auto)):
                mine, t_mine = ours["frols" if mode == "fixed" else "select"]
                ok_theirs, ok_mine = theirs == truth, mine == truth
                totals[mode][0] += 1
                totals[mode][1] += ok_theirs
                totals[mode][2] += ok_mine
                ratios[mode].append(t_theirs / t_mine)
                print(f"{m['name']:<13} {m['samples']:>7} {p:>3} {mode:<5} {'exact' if ok_theirs else 'MISS':>10} "
                      f"{'exact' if ok_mine else 'MISS':>6} {t_theirs:>11.4f}s {t_mine:>8.5f}s {t_theirs / t_mine:>6.0f}x"
                      f"  {truth} | {theirs} | {mine}")
    print()
    for mode in ("fixed", "auto"):
        n, a, b = totals[mode]
        r = sorted(ratios[mode])
        print(f"{mode}: exact structure SysIdentPy {a}/{n}, ours {b}/{n}; speed ratio (SysIdentPy time / ours) "
              f"median {r[len(r) // 2]:.0f}x, min {r[0]:.0f}x")


if __name__ == "__main__":
    main()
