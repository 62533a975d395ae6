"""Benchmark of the self-sensing estimator and the closed loop (synthetic virtual rig, seed 1).

    python bench/bench_observer.py [--quick]

Reports: per-sample ``SelfSensingObserver.step`` time, the compiled batch per
sample, a 10-minute 1 kHz log (600,000 samples; 60,000 with --quick, scaled),
the same filter in plain Python (NUMBA_DISABLE_JIT=1, in a subprocess of this
run) and the ratio; then the estimator's error and the closed-loop RMS with
calibrated (perturbed) parameters on the virtual rig with a load change.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tcamlab.config import load_experiment  # noqa: E402
from tcamlab.estimation import control as ct  # noqa: E402
from tcamlab.estimation import observer as so  # noqa: E402


def _log(config, n, seed=1):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 1e-3
    v = 3.0 + 2.0 * np.sin(2 * np.pi * t / 20.0)
    i = v / config.initial_resistance + so.DEFAULT_NOISE["sd_current"] * rng.standard_normal(n)
    return t, v, i


def _python_reference(n):
    code = (
        f"import time,sys; sys.path.insert(0, {str(ROOT)!r})\n"
        "from bench.bench_observer import _config, _log\n"
        "from tcamlab.estimation import observer as so\n"
        f"c=_config(); t,v,i=_log(c,{n}); t0=time.perf_counter(); so.estimate(t,v,i,c); "
        "print(time.perf_counter()-t0)"
    )
    env = {**os.environ, "NUMBA_DISABLE_JIT": "1"}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    return float(out.stdout.strip().splitlines()[-1]) / n


def _config():
    return so.observer_config(load_experiment(ROOT / "experiments" / "dynamic.toml"))


def speed(config, quick):
    t, v, i = _log(config, 1000)
    so.estimate(t, v, i, config)  # compile
    obs = so.SelfSensingObserver(config, dt=1e-3)
    obs.step(v[0], i[0])
    t0 = time.perf_counter()
    for k in range(1, 1000):
        obs.step(v[k], i[k])
    per_step = (time.perf_counter() - t0) / 999
    n = 60_000 if quick else 600_000
    t, v, i = _log(config, n)
    t0 = time.perf_counter()
    so.estimate(t, v, i, config)
    batch = time.perf_counter() - t0
    ref = _python_reference(2000 if quick else 10_000)
    return per_step, batch / n, batch * 600_000 / n, ref


def accuracy(config, quick, load_logged):
    sc = ct.Scenario(duration=60.0 if quick else 120.0, load_change_at=30.0 if quick else 60.0)
    study = ct.closed_loop_study(config, sc, so.combined_resistance, load_logged=load_logged)
    e = study.results["laser"].estimate_error
    return study, float(np.mean(e)), float(np.percentile(e, 97.5) - np.percentile(e, 2.5)), sc.stroke


def independent():
    """The selfsensing kind's sample runs (raw/, made by that kind's own virtual rig), stated parameters."""
    from tcamlab.io import read_run

    exp = load_experiment(ROOT / "experiments" / "selfsensing.toml")
    for run in exp.runs:
        data = read_run(run, "selfsensing", exp.columns).data
        meas = data["displacement"].to_numpy() - data["displacement"].iloc[0]
        for use_load in (True, False):
            e = so.predict_displacement(exp.sample, exp.rig, data, use_load=use_load)["displacement"] - meas
            width = np.percentile(e, 97.5) - np.percentile(e, 2.5)
            label = "load logged" if use_load else "load unknown"
            print(f"  {run.name} ({label}): stroke {np.ptp(meas) * 1e3:.2f} mm, mean {np.mean(e) * 1e6:.1f} um, "
                  f"95% interval {width * 1e6:.1f} um ({width / np.ptp(meas):.1%})")  # fmt: skip


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args(argv)
    config = _config()
    per_step, per_sample, ten_min, ref = speed(config, args.quick)
    print(f"step(): {per_step * 1e6:.1f} us/sample (goal < 50 us)")
    print(f"batch: {per_sample * 1e6:.2f} us/sample; 10 min at 1 kHz: {ten_min:.2f} s (goal < 5 s)")
    print(
        f"plain Python (NUMBA_DISABLE_JIT): {ref * 1e6:.0f} us/sample; batch {ref / per_sample:.0f}x faster"
    )
    for logged in (False, True):
        study, mean, width, stroke = accuracy(config, args.quick, logged)
        print(f"load {'logged' if logged else 'unknown'}: stroke {stroke * 1e3:.2f} mm; estimate error mean "
              f"{mean * 1e6:.1f} um ({mean / stroke:.1%}), 95% interval {width * 1e6:.1f} um "
              f"({width / stroke:.1%}); goals 2% and 10%")  # fmt: skip
        for m, v in study.rms.items():
            after = study.rms_after_load_change[m]
            print(f"  closed loop {m}: RMS {v * 1e6:.1f} um, after the load change {after * 1e6:.1f} um")
        print(f"  self-sensing / laser RMS: {study.rms['self-sensing'] / study.rms['laser']:.2f} (goal <= 2)")
    print("independent data (the selfsensing kind's virtual rig):")
    independent()


if __name__ == "__main__":
    main()
