"""Score a stored diagnosis-benchmark run again with the current ``tcamlab.benchmark.score``.

The raw results of a run (``benchmark.json``, gzipped in ``bench/reference``) keep every case's
verdict, ranking and per-candidate shrinkage, so a change of the scoring rules (not of the
diagnosis) can be applied to a run that took 45 minutes without running it again.

    python bench/rescore_benchmark.py bench/reference/benchmark_diagnose_full_2026-11-24.json.gz OUT.md

Four static calibration-only cases of the 2026-11-24 full run (seeds 7003, 7005, 7006, 7008)
failed in the virtual rig, not in the diagnosis (G_t' of (2.13) non-positive inside the oven
range; re-run to confirm), before ``run_task`` recorded the stage: they are marked as such.
"""

from __future__ import annotations

import gzip
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tcamlab.benchmark import BenchmarkResult, markdown, score  # noqa: E402

SIMULATE_FAILURES = {("calibration-only", "static", seed) for seed in (7003, 7005, 7006, 7008)}


def main(src: str, out: str) -> None:
    opener = gzip.open if src.endswith(".gz") else open
    with opener(src, "rt", encoding="utf-8") as f:
        d = json.load(f)
    for r in d["results"]:
        if "error" in r and (r["case"], r["kind"], r["seed"]) in SIMULATE_FAILURES:
            r.setdefault("error_stage", "simulate")
    res = BenchmarkResult(scores=score(d["results"]), results=d["results"], settings=d["settings"])
    Path(out).write_text(markdown(res), encoding="utf-8")
    print(f"wrote {out}")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit("usage: python bench/rescore_benchmark.py RUN.json[.gz] OUT.md")
    main(sys.argv[1], sys.argv[2])
