#!/usr/bin/env python
"""Speed of ``tcamlab.calibration.calibrate`` against a plain scipy calibration, same run.

Run from the repository root::

    python bench/bench_calibrate.py           # four kinds, five-run virtual-rig experiments
    python bench/bench_calibrate.py --quick   # bundled dynamic, C_th, lambda, b only (CI smoke run)
    python bench/bench_calibrate.py --json out.json

What is timed, per experiment (wall time of one call, after a warm-up call that compiles
the numba kernels):

a. ``calibrate([experiment])``: MAP, Laplace covariance, profile intervals of every
   parameter, zeros and words.
b. The reference: the same :class:`~tcamlab.calibration.problem.CalibrationProblem`
   (same residuals and priors) fitted the straightforward way, as the first calibration
   did: numba's default thread count, ``scipy.optimize.least_squares`` with its own
   ``jac="2-point"``; the profile bound of each side is a ``brentq`` root of
   ``z(c) - 1.96`` bracketed by doubling steps from the Laplace bound, every point a full
   re-optimisation of the other parameters from the MAP.

The figures printed: both times, their ratio, and the largest difference between the two
profile bounds in Laplace sds (the fast path must agree). The five-run experiments are
synthetic: ``tcamlab.rig.simulate`` of the bundled templates, seed 5, ``parameter_error=1``,
``noisy_zero=True``, in a temporary directory. Nothing asserts on time; a row prints PASS or
FAIL against the 10 s goal of one five-run experiment.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy import optimize

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

from tcamlab.calibration import calibrate  # noqa: E402
from tcamlab.calibration.core import load_experiments  # noqa: E402
from tcamlab.calibration.fit import Z95  # noqa: E402
from tcamlab.calibration.problem import CalibrationProblem  # noqa: E402

GOAL_S = 10.0
KINDS = ("dynamic", "static", "sensing", "curvature")
SEED = 5
QUICK = ["thermal_mass", "heat_loss", "damping"]
"""--quick calibrates the dynamic rig's three parameters only (rho and the G_t slope held)."""


def _lsq(problem, start, free):
    lo, hi = problem.bounds()
    u = np.array(start, float)

    def fun(x):
        v = u.copy()
        v[free] = x
        return problem.residuals(v)

    x0 = np.clip(u[free], lo[free] + 1e-12, hi[free] - 1e-12)
    sol = optimize.least_squares(
        fun, x0, jac="2-point", bounds=(lo[free], hi[free]), x_scale=problem.sd_u[free], method="trf"
    )
    u[free] = sol.x
    return u, 2 * sol.cost


def reference(path, params=None) -> dict[str, tuple[float, float]]:
    """Profile 95 % bounds [fitted coordinates] of every parameter, the plain way."""
    exps = load_experiments([path])
    problem = CalibrationProblem(exps, [e.read_runs() for e in exps], params)
    n = len(problem.specs)
    u, chi2 = _lsq(problem, problem.u0, list(range(n)))
    jac = optimize.approx_fprime(u, problem.residuals, 1e-6)
    cov = np.linalg.pinv(jac.T @ jac)
    lo, hi = problem.bounds()
    out = {}
    for k, spec in enumerate(problem.specs):
        free = [m for m in range(n) if m != k]

        def z(c, k=k, free=free):
            start = u.copy()
            start[k] = c
            return np.sqrt(max(_lsq(problem, start, free)[1] - chi2, 0.0)) - Z95

        bounds = []
        for side, edge in ((-1, lo[k]), (1, hi[k])):
            step = Z95 * np.sqrt(cov[k, k])
            c = u[k] + side * step
            while side * (c - edge) < 0 and z(c) < 0:
                step *= 2
                c = u[k] + side * step
            c = min(max(c, lo[k]), hi[k])
            bounds.append(c if z(c) < 0 else optimize.brentq(z, u[k], c, xtol=1e-3 * np.sqrt(cov[k, k])))
        out[spec.name] = (bounds[0], bounds[1], np.sqrt(cov[k, k]), spec)
    return out


def bench_one(label: str, path, params=None) -> dict:
    calibrate([path], params)  # warm-up: numba compiles on the first call
    t = time.perf_counter()
    result = calibrate([path], params)
    fast = time.perf_counter() - t
    t = time.perf_counter()
    ref = reference(path, params)
    slow = time.perf_counter() - t
    worst = 0.0
    for p in result.parameters:
        lo, hi, sd, spec = ref[p.name]
        for mine, theirs, is_open in zip(p.profile_95, (lo, hi), p.profile_open):
            if not is_open:
                worst = max(worst, abs(spec.to_u(mine) - theirs) / sd)
    row = {
        "experiment": label,
        "calibrate_s": fast,
        "reference_s": slow,
        "ratio": slow / fast,
        "max_bound_difference_sd": worst,
        "goal": "PASS" if fast < GOAL_S else "FAIL",
    }
    print(
        f"{label:34s} calibrate {fast:6.2f} s | reference {slow:7.2f} s | {slow / fast:5.1f}x | "
        f"bounds agree to {worst:.3f} Laplace sd | < {GOAL_S:.0f} s: {row['goal']}",
        flush=True,
    )
    return row


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="the bundled dynamic experiment only")
    ap.add_argument("--json", type=Path, help="also write the rows as JSON")
    args = ap.parse_args(argv)
    rows = []
    if args.quick:
        rows.append(
            bench_one(
                "bundled dynamic (3 runs; C_th, lambda, b)", REPO / "experiments" / "dynamic.toml", QUICK
            )
        )
    else:
        from tcamlab.rig import simulate

        with tempfile.TemporaryDirectory() as tmp:
            for kind in KINDS:
                res = simulate(
                    kind,
                    REPO / "tcamlab" / "templates" / f"{kind}.toml",
                    seed=SEED,
                    out_dir=tmp,
                    n_runs=5,
                    parameter_error=1.0,
                    noisy_zero=True,
                )
                rows.append(bench_one(f"{kind} (5 runs, synthetic seed {SEED})", res.experiment_path))
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
