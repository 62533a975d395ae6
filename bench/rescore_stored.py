"""Score stored diagnosis-benchmark runs again in place, when the scoring rules change.

The raw results of each case (verdict, ranking, every candidate's held-out shrinkage) stay as
the run made them; only the ``scores`` block is recomputed with the current
``tcamlab.benchmark.score``, and ``settings["rescored"]`` records the date and commit of the
rules used, which the generated page shows beside the run's own date and commit.

    python bench/rescore_stored.py bench/reference/diagnose_full_2026-11-26_55804c3.json.gz ...
    python scripts/benchmark_page.py          # then regenerate the pages
"""

from __future__ import annotations

import datetime
import gzip
import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tcamlab.benchmark import score  # noqa: E402
from tcamlab.jsonutil import dumps_json  # noqa: E402


def rescore(path: Path, date: str, commit: str) -> None:
    """Rewrite one stored run's scores with the current rules (its results untouched)."""
    with gzip.open(path, "rt", encoding="utf-8") as f:
        d = json.load(f)
    d["scores"] = score(d["results"])
    d["settings"]["rescored"] = {"date": date, "commit": commit}
    with gzip.open(path, "wt", encoding="utf-8") as f:
        f.write(dumps_json(d, indent=1, sort_keys=False))


def main(paths: list[str]) -> None:
    commit = subprocess.run(
        ["git", "rev-parse", "--short=7", "HEAD"], cwd=ROOT, capture_output=True, text=True, check=True
    ).stdout.strip()
    date = datetime.date.today().isoformat()
    for p in paths:
        rescore(Path(p), date, commit)
        print(f"scored again: {p} (rules at {commit}, {date})")


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit("usage: python bench/rescore_stored.py RUN.json.gz [RUN.json.gz ...]")
    main(sys.argv[1:])
