"""Closed loop on the virtual rig (synthetic: tcamlab.estimation.control, seeds in the tests)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tcamlab.config import load_experiment
from tcamlab.estimation import control as ct
from tcamlab.estimation import observer as so

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def config():
    return so.observer_config(load_experiment(ROOT / "experiments" / "dynamic.toml"))


def _step(config, mode):
    truth = ct.truth_config(config, (config.sample, config.rig, config.resistance_tc), so.combined_resistance)
    scenario = ct.Scenario(duration=30.0, load_change=0.0, seed=5)
    time = np.arange(0.0, 30.0, scenario.dt)
    ref = np.where(time >= 2.0, -0.2e-3, 0.0)
    r = ct.simulate_loop(mode, config, truth, scenario, reference=ref)
    return ct.step_metrics(r.time, r.displacement, -0.2e-3, 2.0, 30.0)


@pytest.mark.slow
def test_laser_step_response(config):
    m = _step(config, "laser")
    # PI designed for a 1 rad/s first-order loop; measured 10% overshoot (the mechanics
    # and the one-sample delay are outside the design), 2% settling slower than 4/wc
    assert m["overshoot"] < 0.15
    assert 1.0 < m["settling_time"] < 12.0  # measured 9.4 s: the 2% band (4 um) is below one laser code
    assert abs(m["final_error"]) < 5e-6


def test_self_sensing_step_response(config):
    m = _step(config, "self-sensing")
    assert m["overshoot"] < 0.15
    # measured 57 um with exact parameters: the estimate's own bias (README); it did track
    assert abs(m["final_error"]) < 0.4 * 0.2e-3


def test_step_metrics_on_a_known_curve():
    t = np.linspace(0, 10, 10001)
    y = 1 - np.exp(-t) * (np.cos(3 * t) + np.sin(3 * t) / 3)  # overshoot exp(-pi/3) = 0.351
    m = ct.step_metrics(t, y, 1.0, 0.0, 10.0)
    assert m["overshoot"] == pytest.approx(np.exp(-np.pi / 3), rel=1e-3)
    assert 3.0 < m["settling_time"] < 4.2  # envelope exp(-t) < 0.02 at t = 3.9


def test_feedback_beats_open_loop_under_a_load_change(config):
    # calibrated-size parameter errors (control.PERTURBATION), a 3 mN load step at 60 s, logged
    study = ct.closed_loop_study(
        config, ct.Scenario(duration=120.0, seed=1), so.combined_resistance, load_logged=True
    )
    assert study.rms["laser"] < 0.5 * study.rms["open-loop"]
    assert study.rms["self-sensing"] < 0.5 * study.rms["open-loop"]
    assert study.rms["self-sensing"] < 2.0 * study.rms["laser"]  # measured 1.01x
    e = study.results["laser"].estimate_error
    stroke = study.scenario.stroke
    assert abs(np.mean(e)) < 0.03 * stroke  # measured 0.1 %
    assert np.percentile(e, 97.5) - np.percentile(e, 2.5) < 0.10 * stroke  # measured 7.4 %


@pytest.mark.slow
def test_closed_loop_command_writes_the_report_and_refuses_to_overwrite(tmp_path):
    import json
    import subprocess
    import sys

    cmd = [sys.executable, "-m", "tcamlab", "closed-loop", str(ROOT / "experiments" / "dynamic.toml")]
    cmd += ["--out", str(tmp_path), "--duration", "20"]
    first = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    assert first.returncode == 0, first.stderr
    folder = tmp_path / "dynamic"
    assert (folder / "closed_loop.pdf").read_bytes()[:5] == b"%PDF-"
    assert "SYNTHETIC" in (folder / "closed_loop.html").read_text()
    summary = json.loads((folder / "closed_loop.json").read_text())
    assert set(summary["regimes"]) == {"load unknown", "load logged"}
    again = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    assert again.returncode == 2 and "--force" in again.stderr and "Traceback" not in again.stderr


def test_self_sensing_tracks_within_twice_the_laser_with_the_load_unknown(config):
    # calibrated-size parameter errors, a 3 mN load step at 60 s told to nobody (synthetic, seed 2)
    scenario = ct.Scenario(duration=120.0, seed=2)
    study = ct.closed_loop_study(config, scenario, so.combined_resistance)
    assert study.rms["self-sensing"] < 2.0 * study.rms["laser"]  # measured 1.86x (48.0 / 25.7 um)
    assert study.rms["self-sensing"] < 0.7 * study.rms["open-loop"]  # measured 0.59
    # the cause of the old 4.8x: with theta off the thermal model's error went into the load
    old = ct.closed_loop_study(config, scenario, so.combined_resistance, unknown_load_noise={})
    assert old.rms["self-sensing"] > 3.0 * old.rms["laser"]  # measured 4.84x
    bias = np.mean(old.results["laser"].estimate_error[old.results["laser"].time < 60.0])
    assert bias > 40e-6  # measured +69 um before the load change


def test_the_loop_kernel_runs_a_configured_jump_detector(config):
    # the kernel carries the detector's sums: a detector that alarms on noise changes the estimate
    truth = ct.truth_config(config, (config.sample, config.rig, config.resistance_tc), so.combined_resistance)
    scenario = ct.Scenario(duration=5.0, load_change=0.0, seed=4)
    off = ct.simulate_loop("self-sensing", config, truth, scenario)
    noisy = config.with_noise(jump_drift=0.0, jump_threshold=1.0, jump_sd=0.05, jump_hold=1.0)
    on = ct.simulate_loop("self-sensing", noisy, truth, scenario)
    assert np.max(np.abs(on.estimate - off.estimate)) > 10e-6
