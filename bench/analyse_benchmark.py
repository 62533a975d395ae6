"""Two figures of a stored diagnosis-benchmark run that show which targets the data can reach.

1. **Recalibration against the true effect on withheld runs.** For every effect case the
   diagnosis called ``miscalibrated`` (and is not right by the parameter the effect is), the
   ratio of recalibration's held-out RMSE to the true effect's (each fitted with the
   recalibrated parameters): near 1 the withheld runs cannot tell them apart, so no rule
   scored on withheld data can name the effect there.
2. **The gap the baseline sees.** The median held-out baseline RMSE in noise multiples, by kind
   and strength, beside sqrt(1 + s^2), the value the noise ceiling 1 - 1/sqrt(1 + s^2) of
   the shrinkage target assumes. A strength is the RMS of the raw effect (``rig.strength``);
   the per-run zero the diagnosis profiles out (``Kind.nuisance_zeros``) removes its mean.

    python bench/analyse_benchmark.py bench/reference/benchmark_diagnose_full_2026-11-24.json.gz
"""

from __future__ import annotations

import gzip
import json
import math
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tcamlab.benchmark import right, true_effect  # noqa: E402

FAMILIES = ("single", "realistic")


def _strength(r: dict) -> float:
    return float(next(iter({**r["effects"], **r.get("offlibrary", {})}.values())))


def load(src: str) -> list[dict]:
    opener = gzip.open if src.endswith(".gz") else open
    with opener(src, "rt", encoding="utf-8") as f:
        return json.load(f)["results"]


def recalibration_ratios(results: list[dict]) -> dict:
    """{(case, strength): [recalibration / true effect held-out RMSE]} of the miscalibrated misses."""
    cells = defaultdict(list)
    for r in results:
        if r["case"] not in FAMILIES or "error" in r or r["verdict"] != "miscalibrated" or right(r):
            continue
        sh, t = r["shrinkage"], true_effect(r)
        if t in sh and "recalibration" in sh and sh[t] is not None and sh[t] < 1:
            cells[(r["case"], _strength(r))].append((1 - sh["recalibration"]) / (1 - sh[t]))
    return cells


def baseline_gaps(results: list[dict]) -> dict:
    """{(kind, strength): [held-out baseline RMSE / noise]} of the effect-only single cases."""
    cells = defaultdict(list)
    for r in results:
        if r["case"] == "single" and "error" not in r and r.get("heldout_rmse_before_noise"):
            cells[(r["kind"], _strength(r))].append(r["heldout_rmse_before_noise"])
    return cells


def main(src: str) -> None:
    results = load(src)
    n_single = sum(r["case"] == "single" and "error" not in r for r in results)
    print("| family | strength | miscalibrated misses | median recalibration / true effect | 10-90 % |")
    print("|---|---|---|---|---|")
    for (case, s), v in sorted(recalibration_ratios(results).items()):
        lo, hi = np.nanpercentile(v, [10, 90])
        fam = "effect-only" if case == "single" else case
        print(f"| {fam} | {s:g}x | {len(v)} | {np.nanmedian(v):.3f} | {lo:.3f}-{hi:.3f} |")
    print(f"\n({n_single} effect-only cases in the run)\n")
    print("| kind | strength | cases | median baseline held-out RMSE / noise | sqrt(1 + s^2) |")
    print("|---|---|---|---|---|")
    for (kind, s), v in sorted(baseline_gaps(results).items()):
        print(f"| {kind} | {s:g}x | {len(v)} | {np.median(v):.2f} | {math.sqrt(1 + s * s):.2f} |")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: python bench/analyse_benchmark.py RUN.json[.gz]")
    main(sys.argv[1])
