"""Tests of the withheld-effect benchmark (tcamlab.benchmark)."""

from __future__ import annotations

import json
import math

import pytest

from tcamlab import benchmark
from tcamlab.benchmark import make_tasks, run_benchmark, score

pytest.importorskip("tcamlab.rig")


def _check_outputs(out, res):
    data = json.loads((out / "benchmark.json").read_text())
    assert data["scores"]["accuracy_by_strength"]
    assert (out / "benchmark.md").read_text().startswith("# Withheld-effect benchmark")
    assert (out / "benchmark.html").exists() and (out / "benchmark.pdf").exists()
    assert not res.scores["errors"], res.scores["errors"]


def test_quick_benchmark_tiny_subset(tmp_path):
    res = run_benchmark(
        tmp_path, quick=True, seeds=1, kinds=("dynamic",), effects=["response-delay"], workers=1
    )
    assert len(res.results) == 2  # one effect case + one null case
    _check_outputs(tmp_path, res)
    single = [r for r in res.results if r["case"] == "single"][0]
    assert single["effects"] == {"response-delay": 3.0}
    assert single["ranking"][0] == "response-delay"
    assert single["truth_values"]["response-delay"]["delay"] != 0
    assert "| strength |" in (tmp_path / "benchmark.md").read_text()


def test_dask_path_with_local_cluster(tmp_path):
    distributed = pytest.importorskip("dask.distributed")
    with distributed.LocalCluster(
        n_workers=1, processes=False, threads_per_worker=1, dashboard_address=None
    ) as cluster:
        res = run_benchmark(
            tmp_path,
            quick=True,
            seeds=1,
            kinds=("curvature",),
            effects=["sensor-offset-error"],
            scheduler=cluster.scheduler_address,
        )
    assert res.settings["executor"] == "dask"
    assert len(res.results) == 2
    _check_outputs(tmp_path, res)


def test_task_lists():
    quick = make_tasks(quick=True)
    full = make_tasks(seeds=10)
    assert {t["case"] for t in quick} == {"single", "null"}
    assert all(next(iter(t["effects"].values())) == 3.0 for t in quick if t["case"] == "single")
    assert {t["case"] for t in full} == {"single", "null", "pair"}
    singles = [t for t in full if t["case"] == "single"]
    assert {next(iter(t["effects"].values())) for t in singles} == set(benchmark.STRENGTHS)
    assert len({t["seed"] for t in singles}) == 10


def test_scoring_rules():
    def single(truth, verdict, effect, ranking, s=3.0):
        return {
            "case": "single",
            "kind": "static",
            "effects": {truth: s},
            "seed": 1,
            "verdict": verdict,
            "effect": effect,
            "aliased_with": [],
            "ranking": ranking,
            "shrinkage": {e: 0.6 for e in ranking},
            "fitted": {},
            "truth_values": {},
            "fraction_closed": {e: 0.9 for e in ranking},
            "heldout_rmse_before_noise": 4.0,
            "seconds": 1.0,
        }

    results = [
        single("a", "attributed", "a", ["a", "b", "c"]),
        single("a", "aliased", "b", ["b", "a", "c"]),
        single("a", "unexplained", None, ["a", "b"]),
        {
            "case": "null",
            "kind": "static",
            "effects": {},
            "seed": 2,
            "verdict": "attributed",
            "effect": "b",
            "aliased_with": [],
            "ranking": ["b"],
            "seconds": 1.0,
        },
        {
            "case": "pair",
            "kind": "static",
            "effects": {"a": 5.0, "b": 5.0},
            "seed": 3,
            "verdict": "attributed",
            "effect": "c",
            "aliased_with": [],
            "ranking": ["c"],
            "seconds": 1.0,
        },
    ]
    s = score(results)
    acc = s["accuracy_by_strength"]["3.0"]
    assert acc["top1"] == pytest.approx(1 / 3) and acc["top3"] == pytest.approx(2 / 3)
    assert s["null"]["rate"] == 1.0
    assert s["pairs"][0]["outcome"].startswith("confident third")
    assert s["confusion"]["static"]["a"] == {"a": 1, "b": 1, "unexplained": 1}
    # one right attribution: shrinkage 0.6 of an attainable 1 - 1/4 = 0.75
    cell = s["shrinkage_by_strength"]["3.0"]
    assert cell["n"] == 1 and cell["median_shrinkage"] == pytest.approx(0.6)
    assert cell["median_share_of_attainable"] == pytest.approx(0.8)
    assert cell["noise_ceiling"] == pytest.approx(1 - 1 / math.sqrt(10), rel=1e-12)
    assert s["median_fraction_closed_when_right"] == pytest.approx(0.9)
