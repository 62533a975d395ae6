"""Operations on logged signals (tcamlab.signals): a slower instrument's reading found and
averaged over its frames, checked on forms this module did not make (SYNTHETIC series, seeds
given; the bundled stepped pull test's resistance)."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from tcamlab import signals
from tcamlab.io import read_run

ROOT = __import__("pathlib").Path(__file__).resolve().parent.parent


def _camera(rows=60_000, seed=1, per_frame=40, sd=0.5, digits=1, jitter_s=0.0):
    """A 1 kHz log of an oven's heat-cool cycle read by a camera every ``per_frame`` rows, its
    frames time-stamped to +-``jitter_s`` (SYNTHETIC, seed ``seed``): (true temperature,
    frames held, frames interpolated)."""
    rng = np.random.default_rng(seed)
    t = np.arange(rows) / 1000.0
    true = 25.0 + 27.5 * (1.0 - np.cos(2.0 * np.pi * t / 60.0))
    tf = np.arange(0.0, t[-1] + per_frame / 1000.0, per_frame / 1000.0)
    tf = np.sort(tf + rng.uniform(-jitter_s, jitter_s, tf.size)) if jitter_s else tf
    frame = 25.0 + 27.5 * (1.0 - np.cos(2.0 * np.pi * tf / 60.0)) + rng.normal(0, sd, tf.size)
    frame = np.round(frame, digits)
    if jitter_s:
        held = frame[np.clip(np.searchsorted(tf, t, side="right") - 1, 0, tf.size - 1)]
    else:
        held = frame[np.clip(np.round(t * 1000.0 / per_frame).astype(int), 0, tf.size - 1)]
    return true, held, np.round(np.interp(t, tf, frame), 4)


@pytest.mark.parametrize("per_frame", [7, 40, 125])
def test_a_camera_held_or_interpolated_onto_a_faster_log_is_found_with_its_frame(per_frame):
    _, held, interp = _camera(per_frame=per_frame)
    for x in (held, interp):
        period, starts = signals.instrument_frames(x)
        assert period == per_frame
        gaps = np.diff(starts)[1:]  # whole frames (two frames read alike merge), to a row
        assert starts[0] == 0 and np.all(np.abs(gaps - per_frame * np.round(gaps / per_frame)) <= 1)


@pytest.mark.parametrize("jitter_s", [0.005, 0.008])
def test_a_camera_whose_frame_times_jitter_is_found_and_averaged(jitter_s):
    """Frame time stamps jittering by up to a fifth of a frame: the edges of held frames move,
    and an interpolated frame between two rows bends the line at both."""
    true, held, interp = _camera(seed=8, jitter_s=jitter_s)
    for x in (held, interp):
        smooth, info = signals.smooth_slow_input(x)
        assert info is not None and info["rows_per_frame"] == 40
        assert float(np.sqrt(np.mean((smooth - true) ** 2))) < 0.15


def test_a_reading_on_every_row_or_a_stepped_test_is_no_slower_instrument():
    rng = np.random.default_rng(2)
    true, _, _ = _camera()
    assert signals.instrument_frames(true + rng.normal(0, 0.5, true.size))[0] == 1  # a thermocouple
    assert signals.instrument_frames(np.round(true, 1))[0] == 1  # a slow reading, coarse digits
    # a pull held at regular steps, its ohmmeter's noise on every row (the bundled pull test)
    steps = np.repeat(np.arange(60) * 0.025, 50) + 30.0 + rng.normal(0, 0.002, 3000)
    assert signals.instrument_frames(np.round(steps, 3))[0] == 1
    bundled = pd.read_csv(ROOT / "raw" / "sensing_run1.csv")["resistance_ohm"].to_numpy(float)
    assert signals.instrument_frames(bundled)[0] == 1


def test_the_frame_average_keeps_a_line_to_both_ends_and_averages_the_rest():
    t = np.arange(1000.0)
    line = 3.0 - 0.25 * t
    np.testing.assert_allclose(signals.frame_average(line, 101), line, atol=1e-9)
    x = np.random.default_rng(3).normal(0, 1, 1000)
    assert signals.frame_average(x, 101)[500] == pytest.approx(np.mean(x[450:551]))


def test_the_averaged_camera_is_the_true_temperature_to_its_noise_over_the_frames():
    true, held, interp = _camera(seed=4)
    for x in (held, interp):
        smooth, info = signals.smooth_slow_input(x)
        assert info["rows_per_frame"] == 40 and info["frames"] == 32
        assert info["frame_sd"] == pytest.approx(0.5, rel=0.05)  # written to 0.1 degC
        rms = float(np.sqrt(np.mean((smooth - true) ** 2)))
        assert rms < 1.5 * 0.5 / math.sqrt(32)  # the camera's noise over 32 frames
        assert float(np.sqrt(np.mean((x - true) ** 2))) > 4 * rms
        assert abs(float(np.mean(smooth - true))) < 0.02  # centred: no lag, no offset


def test_an_input_that_moves_within_a_few_frames_is_left_as_logged():
    """A 20 degC square wave of 40 frames under 0.1 degC of camera noise (SYNTHETIC, seed 5):
    any average over whole frames would bend its edges by more than the noise it removes."""
    rng = np.random.default_rng(5)
    frame = 20.0 * (np.arange(1500) // 20 % 2) + rng.normal(0, 0.1, 1500)
    x = np.repeat(frame, 40)
    assert signals.instrument_frames(x)[0] == 40
    out, info = signals.smooth_slow_input(x)
    assert info is None
    np.testing.assert_array_equal(out, x)


def test_reading_a_run_averages_its_camera_and_keeps_the_file(tmp_path):
    true, held, _ = _camera(rows=20_000, seed=6)
    t = np.arange(true.size) / 1000.0
    disp = -5.7e-3 * (true - true[0])
    path = tmp_path / "run.csv"
    pd.DataFrame({"time_s": t, "temperature_C": held, "displacement_mm": np.round(disp, 3)}).to_csv(
        path, index=False
    )
    before = path.read_bytes()
    run = read_run(path, "static")
    assert path.read_bytes() == before
    assert set(run.smoothed) == {"temperature"}
    assert run.smoothed["temperature"]["rows_per_frame"] == 40
    err = run.data["temperature"].to_numpy() - true
    assert float(np.sqrt(np.mean(err**2))) < 0.15
    # a column that is no noisy input of the kind is never touched
    np.testing.assert_allclose(
        run.data["displacement"].to_numpy() * 1e3, np.round(disp, 3) - np.round(disp, 3)[0]
    )


def test_a_lag_of_a_ramp_read_on_a_coarse_grid_trails_it_by_tau_with_the_midpoint_hold():
    """y' = (x - y) / tau on x = 2 t: after the start, y = x - 2 tau. Sampled every 64 ms,
    holding each sample's value over the step before it leads x by half a step; holding the
    step's mean does not (to second order in the step)."""
    tau, step = 0.5, 0.064
    t = np.arange(0.0, 10.0, step)
    x = 2.0 * t
    end = signals.first_order_lag(x, t, tau)
    mid = signals.first_order_lag(x, t, tau, hold="midpoint")
    late = t > 8 * tau
    assert np.max(np.abs(x - mid - 2.0 * tau)[late]) < 2.0 * step**2 / (12 * tau)
    assert np.median((x - end - 2.0 * tau)[late]) == pytest.approx(-2.0 * step / 2, rel=0.05)
    exact = x - 2.0 * tau * (1.0 - np.exp(-t / tau))  # from rest, the transient included
    assert np.max(np.abs(mid - exact)) < 2.0 * step**2 / (12 * tau)


@pytest.mark.parametrize("pattern", [[0.0, 1.0], [0.0, 0.0, 1.0, 1.0], [0.0, 1.0, 1.0]])
def test_a_drive_stepped_at_every_few_frames_is_a_signal_not_noise(pattern):
    """A commanded input held between regular steps looks like a slower instrument's frames
    (evenly spaced edges, nothing in between), but its frame-to-frame changes repeat: never
    averaged."""
    x = np.repeat(np.tile(pattern, 400) * 3.0 + 1.0, 50)
    assert signals.instrument_frames(x)[0] in (1, 50, 100)  # found as frames, or irregular
    out, info = signals.smooth_slow_input(x)
    assert info is None
    np.testing.assert_array_equal(out, x)


def test_too_few_frames_to_tell_noise_from_a_pattern_are_left_alone():
    true, held, _ = _camera(rows=3_000, seed=7)  # 75 frames
    assert signals.smooth_slow_input(held)[1] is None


def test_block_means_keep_a_constant_misfits_sum_of_squares_and_the_noises_variance():
    z = np.array([1.0, 1.0, 1.0, 1.0, 2.0, 2.0, 3.0, 3.0, 3.0, 3.0, 4.0, 4.0])
    # two stacked parts of six rows, blocks of four: the last block of each part has two rows
    got = signals.block_means(z, 2, 4)
    assert got == pytest.approx([2.0, 4.0 / math.sqrt(2.0), 6.0, 8.0 / math.sqrt(2.0)])
    assert np.sum(got[:2] ** 2) == pytest.approx(np.sum(z[:6] ** 2))  # constant per block
    noise = np.random.default_rng(3).normal(0.0, 1.0, 64_000)
    assert np.var(signals.block_means(noise, 1, 16)) == pytest.approx(1.0, abs=0.03)
    assert signals.n_blocks(6, 4) == 2 and signals.n_blocks(6, 1) == 6


def test_step_rows_marks_the_rows_either_side_of_a_commanded_step_only():
    v = np.r_[np.zeros(50), np.full(100, 4.0), np.zeros(50)]
    rows = signals.step_rows([v])
    assert np.flatnonzero(rows).tolist() == [49, 50, 149, 150]
    # a column that moves on most rows (an oven's reading) is not piecewise constant
    ramp = np.linspace(20.0, 80.0, 200) + np.random.default_rng(0).normal(0, 0.1, 200)
    assert not signals.step_rows([ramp]).any()


def test_second_differences_across_a_step_are_left_out_of_the_noise():
    """White noise of sd 1 plus a residual that jumps by 30 at two steps (what a model misses of a
    step response): taken in, the jumps read as noise; left out, the sd is the noise's."""
    rng = np.random.default_rng(3)
    v = np.r_[np.zeros(300), np.full(400, 4.0), np.zeros(300)]
    r = rng.normal(0.0, 1.0, v.size) + np.where(v > 0, 30.0, 0.0)
    assert signals.second_difference_sigma(r) > 1.2
    assert signals.second_difference_sigma(r, signals.step_rows([v])) == pytest.approx(1.0, rel=0.08)
    # a mask that leaves nothing out, or does not fit, changes nothing
    assert signals.second_difference_sigma(r, np.zeros(v.size, bool)) == signals.second_difference_sigma(r)
    assert signals.second_difference_sigma(r, np.ones(3, bool)) == signals.second_difference_sigma(r)


def test_robust_second_difference_sigma_reads_noise_through_steps_and_gaps():
    """Noise of sd 0.5 on a ramp with two jumps of 40 and a NaN row: the median of the second
    differences ignores the jumps (the plain estimate does not) and the NaN is dropped."""
    rng = np.random.default_rng(11)
    x = np.linspace(0.0, 5.0, 4000) + rng.normal(0.0, 0.5, 4000) + np.where(np.arange(4000) > 2000, 40.0, 0.0)
    x[1500] = np.nan
    assert signals.robust_second_difference_sigma(x) == pytest.approx(0.5, rel=0.06)
    assert signals.second_difference_sigma(x[np.isfinite(x)]) > 0.6
    assert np.isnan(signals.robust_second_difference_sigma([1.0, np.nan, 2.0]))
