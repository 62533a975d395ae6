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
