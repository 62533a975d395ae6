#!/usr/bin/env python
"""Speed of one evaluation of the self-sensing estimator's refit against a straightforward one.

Run from the repository root::

    python bench/bench_estimator_refit.py            # the bundled experiment, best of 5
    python bench/bench_estimator_refit.py --quick    # smoke run: best of 1

``tcamlab calibrate`` on a selfsensing experiment spends nearly all its time in the second
stage (``tcamlab.calibration.estimator``): each evaluation of its least squares filters every
training run once with the load logged and once withheld, after tabulating R(T, x) for each.
The figure times one evaluation on the bundled ``experiments/selfsensing.toml`` (three 50 s
runs at 100 Hz, SYNTHETIC: the selfsensing virtual rig, seed 1) two ways in this process:

* reference: the passes one after the other, and chapter 3's map solved at every cell of the
  resistance table (121 x 161), as a first implementation writes it;
* tcamlab: the passes on ``FILTER_THREADS`` threads (the filter's kernel releases the GIL) and
  the map solved once per distinct extension.

Both must give the same residuals to the bit (exit 1 otherwise). Nothing asserts on time.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # this checkout's tcamlab


def per_cell_resistance(sample, rig, initial_resistance, resistance_tc, lead=0.0, stretch=1.0, tcr2=0.0):
    """R(T, x) with chapter 3's map solved at every cell (the reference)."""
    from tcamlab.estimation import observer
    from tcamlab.models import selfsensing

    kw, s_c = sample.sensor_kwargs(), observer.spring_constant(sample, rig)

    def resistance(temperature, extension):
        g = selfsensing.geometric_ratio(extension, spring_constant=s_c, **kw)
        dt = np.asarray(temperature, float) - rig.ambient
        coating = selfsensing.coating_factor(temperature, rig.ambient, resistance_tc) + tcr2 * dt**2
        heat = coating * selfsensing.swelling_factor(temperature, rig.ambient, sample.radial_cte)
        return lead + initial_resistance * (1.0 + stretch * (g - 1.0)) * heat

    return resistance


def best_time(fn, u, repeats: int) -> tuple[float, np.ndarray]:
    """(best wall time [s], the residuals) of ``repeats`` calls after one warm-up."""
    out = fn(u)
    best = np.inf
    for _ in range(repeats):
        t = time.perf_counter()
        out = fn(u)
        best = min(best, time.perf_counter() - t)
    return best, out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="smoke run: best of 1")
    args = ap.parse_args(argv)
    from tcamlab.calibration import estimator
    from tcamlab.config import load_experiment
    from tcamlab.estimation import observer

    exp = load_experiment(ROOT / "experiments" / "selfsensing.toml")
    frames = [r.data for r in exp.read_runs()]
    names = list(estimator.PARAMETERS)
    mu, sd = (np.array(x) for x in zip(*(estimator.refit_prior(exp.rig, n, exp.sample) for n in names)))
    fn = estimator._residual_fn(exp.sample, exp.rig, frames, names, mu, sd, (True, False))
    u = np.full(len(names), 0.1)
    repeats = 1 if args.quick else 5
    fast, r_fast = best_time(fn, u, repeats)
    threads, combined = estimator.FILTER_THREADS, observer.combined_resistance
    estimator.FILTER_THREADS, observer.combined_resistance = 1, per_cell_resistance
    try:
        slow, r_slow = best_time(fn, u, repeats)
    finally:
        estimator.FILTER_THREADS, observer.combined_resistance = threads, combined
    same = bool(np.array_equal(r_fast, r_slow))
    print("one evaluation of the estimator's refit, bundled selfsensing experiment (SYNTHETIC)")
    print(f"  reference (serial, map per cell)        {slow:8.3f} s")
    print(f"  tcamlab ({threads} threads, map per extension) {fast:8.3f} s")
    print(f"  ratio {slow / fast:.2f}x; residuals identical: {same}")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
