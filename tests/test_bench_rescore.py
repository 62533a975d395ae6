"""bench/rescore_benchmark.py scores a stored run again (the stored tables, byte for byte)."""

from __future__ import annotations

import runpy
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_rescoring_the_stored_full_run_gives_the_stored_tables(tmp_path, monkeypatch):
    out = tmp_path / "rescored.md"
    src = ROOT / "bench" / "reference" / "benchmark_diagnose_full_2026-11-24.json.gz"
    monkeypatch.setattr(sys, "argv", ["rescore_benchmark.py", str(src), str(out)])
    runpy.run_path(str(ROOT / "bench" / "rescore_benchmark.py"), run_name="__main__")
    text = out.read_text()
    # the four static cases the virtual rig could not make are skipped, not scored
    assert text.count("ModelDomainError") == 4
    # effect-only top-1 at 3x with a miscalibrated d1 / R0 counted right
    assert "| effect-only | top-1 at 3.0x | 170 | 0.594 | >= 0.9 |" in text
    assert (
        text == (ROOT / "bench" / "reference" / "benchmark_diagnose_full_2026-11-24_rescored.md").read_text()
    )


def test_analysis_of_the_stored_run_shows_the_curvature_gap_is_whole_and_the_zeroed_kinds_smaller(capsys):
    mod = runpy.run_path(str(ROOT / "bench" / "analyse_benchmark.py"))
    results = mod["load"](str(ROOT / "bench" / "reference" / "benchmark_diagnose_full_2026-11-24.json.gz"))
    gaps = mod["baseline_gaps"](results)
    import numpy as np

    # curvature has no profiled zero: its baseline sees the whole 10x gap (sqrt(101) = 10.05)
    assert 9.0 < np.median(gaps[("curvature", 10.0)]) < 10.5
    # static's per-run zero removes the effect's mean: about 6, not 10
    assert np.median(gaps[("static", 10.0)]) < 7.0
    ratios = mod["recalibration_ratios"](results)
    assert abs(np.median(ratios[("single", 3.0)]) - 1.0) < 0.01


def test_a_partial_rerun_replaces_the_same_tasks_and_keeps_the_rest():
    mod = runpy.run_path(str(ROOT / "bench" / "merge_benchmark_runs.py"))

    def case(kind, seed, verdict, **kw):
        return {
            "case": "single",
            "kind": kind,
            "effects": {"hysteresis": 3.0},
            "seed": seed,
            "verdict": verdict,
            **kw,
        }

    full = {
        "results": [
            case("sensing", 1000, "none"),
            case("static", 1000, "none"),
            case("sensing", 1001, "none"),
        ],
        "settings": {"seeds": 10},
    }
    part = {
        "results": [case("sensing", 1000, "attributed"), case("sensing", 1002, "aliased")],
        "settings": {"x": 1},
    }
    merged = mod["merge"](full, [part])
    got = {(r["kind"], r["seed"]): r["verdict"] for r in merged["results"]}
    assert got == {
        ("sensing", 1000): "attributed",
        ("static", 1000): "none",
        ("sensing", 1001): "none",
        ("sensing", 1002): "aliased",
    }
    # a quiet null is not the same task as a loud one with the same seed
    assert mod["task_key"](case("dynamic", 1, "none", noise_scale=0.2)) != mod["task_key"](
        case("dynamic", 1, "none")
    )
    assert merged["settings"]["merged_from"] == [{"seeds": 10}, {"x": 1}]
