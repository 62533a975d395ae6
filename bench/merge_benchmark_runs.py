"""Merge a partial re-run of the diagnosis benchmark into a full run, then score the whole.

A change that can only affect some cases (one kind, one family) is re-run on those; each
case of the re-run replaces the full run's case with the same task (family, kind, effects,
out-of-library form, seed, template), and the merged results are scored with the current
``tcamlab.benchmark.score``. The settings record both runs.

    python bench/merge_benchmark_runs.py FULL.json[.gz] PART.json[.gz] [PART2 ...] OUT.json.gz OUT.md
"""

from __future__ import annotations

import gzip
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tcamlab.benchmark import BenchmarkResult, markdown, score  # noqa: E402

TASK_KEYS = ("case", "kind", "effects", "offlibrary", "seed", "template", "noise_scale")
"""What makes two results the same task."""


def _load(path: str) -> dict:
    opener = gzip.open if path.endswith(".gz") else open
    with opener(path, "rt", encoding="utf-8") as f:
        return json.load(f)


def task_key(r: dict) -> str:
    """The task a result answers, as a string (its rows are otherwise the case's outcome)."""
    return json.dumps({k: r.get(k) for k in TASK_KEYS}, sort_keys=True)


def merge(full: dict, parts: list[dict]) -> dict:
    """``full`` with every case of ``parts`` in place of the same task (new tasks appended)."""
    results = {task_key(r): r for r in full["results"]}
    for p in parts:
        results.update({task_key(r): r for r in p["results"]})
    settings = {**full["settings"], "merged_from": [full["settings"]] + [p["settings"] for p in parts]}
    return {"results": list(results.values()), "settings": settings}


def main(args: list[str]) -> None:
    full, parts, out_json, out_md = _load(args[0]), [_load(a) for a in args[1:-2]], args[-2], args[-1]
    d = merge(full, parts)
    d["scores"] = score(d["results"])  # stored as a run's own file stores them (its page reads them)
    with gzip.open(out_json, "wt", encoding="utf-8") as f:
        json.dump(d, f)
    res = BenchmarkResult(scores=d["scores"], results=d["results"], settings=d["settings"])
    Path(out_md).write_text(markdown(res), encoding="utf-8")
    print(f"wrote {out_json} and {out_md} ({len(d['results'])} cases)")


if __name__ == "__main__":
    if len(sys.argv) < 5:
        sys.exit(
            "usage: python bench/merge_benchmark_runs.py FULL.json[.gz] PART.json[.gz] ... OUT.json.gz OUT.md"
        )
    main(sys.argv[1:])
