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
