"""The 10-million-row check of bench/bench_large_log.py (.ci/run runs it): what fails it."""

from __future__ import annotations

import importlib.util
from pathlib import Path

_PATH = Path(__file__).resolve().parents[1] / "bench" / "bench_large_log.py"
_spec = importlib.util.spec_from_file_location("bench_large_log", _PATH)
big = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(big)


def _run(exit_code=0, html_mb=0.49):
    return {"exit": exit_code, "html_mb": html_mb, "output": "wrote x\nerror: out of memory\n"}


def test_check_passes_small_reports_and_fails_big_or_broken_ones():
    assert big.check_failures({"validate": _run(), "report": _run()}) == []
    bad = big.check_failures({"validate": _run(html_mb=5.2), "report": _run(exit_code=2, html_mb=None)})
    assert len(bad) == 2
    assert bad[0].startswith("validate: report.html 5.20 MB >= 5 MB")
    assert bad[1].startswith("report exited 2") and "out of memory" in bad[1]


def test_check_skips_with_a_reason_where_the_machine_cannot_hold_the_log(tmp_path):
    assert big.room_for(1000, tmp_path) is None  # 250 kB of disk, 0.6 MB of memory
    why = big.room_for(10**15, tmp_path)  # 250 PB: no machine has it
    assert why is not None and "GB free under" in why


def test_fit_goals_follow_the_log_length_and_fail_a_slow_or_broken_fit(capsys):
    assert big.fit_goal(142_100) == (20.0, 2000.0)
    assert big.fit_goal(1_000_000) == (60.0, 2000.0)
    assert big.fit_goal(10_000_000) == (600.0, 4000.0)
    fast = {"exit": 0, "wall_s": 19.0, "rss_mb": 500.0, "cpu_s": 18.0}
    slow = dict(fast, wall_s=21.0)
    broken = dict(fast, exit=1)
    big.print_fits(
        {"fit_142100": {"calibrate": fast, "diagnose": slow}, "fit_1000000": {"calibrate": broken}}
    )
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("calibrate") and lines[0].endswith("PASS")
    assert lines[1].startswith("diagnose") and lines[1].endswith("FAIL")  # 21 s > 20 s at 142,100 rows
    assert lines[2].endswith("FAIL")  # exit 1


def test_the_static_log_joins_a_1khz_laser_with_a_25hz_camera(tmp_path):
    """make_static_log (SYNTHETIC, seed 12): the held camera's temperature changes only at
    its frames (every 40 rows at 1 kHz), the interpolated one on every row within a frame;
    both read the same frames (equal at the frame times), the laser column is the same, and
    the file says it is synthetic with its generator and seed."""
    import numpy as np
    import pandas as pd

    held = big.make_static_log(4_000, tmp_path, camera="held")
    interp = big.make_static_log(4_000, tmp_path, camera="interpolated")
    a = pd.read_csv(held.parent / "run1.csv")
    b = pd.read_csv(interp.parent / "run1.csv")
    assert len(a) == len(b) == 4_000
    changes = np.flatnonzero(np.diff(a["temperature_C"].to_numpy()) != 0) + 1
    assert changes.size > 50 and np.all(np.isin(changes % 40, (20, 21)))  # nearest frame: halfway
    assert np.count_nonzero(np.diff(b["temperature_C"].to_numpy()) != 0) > 3_000
    frames = np.arange(0, 4_000, 40)
    np.testing.assert_allclose(
        a["temperature_C"].to_numpy()[frames], b["temperature_C"].to_numpy()[frames], atol=1e-3
    )
    np.testing.assert_array_equal(a["displacement_mm"].to_numpy(), b["displacement_mm"].to_numpy())
    text = held.read_text()
    assert "SYNTHETIC" in text and 'generator = "bench/bench_large_log.py make_static_log"' in text
    assert "seed = 12" in text


def test_fit_lines_carry_the_log_label(capsys):
    fast = {"exit": 0, "wall_s": 5.0, "rss_mb": 500.0, "cpu_s": 5.0}
    big.print_fits({"fit_142100": {"diagnose": fast}}, "static ")
    line = capsys.readouterr().out.strip()
    assert line.startswith("static diagnose") and "142,100 rows" in line and line.endswith("PASS")
