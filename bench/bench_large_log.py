#!/usr/bin/env python
"""``validate`` and ``report`` on a long 1 kHz dynamic log: time, peak RSS, report size.

Run from the repository root::

    python bench/bench_large_log.py            # 10,000,000 rows (about 2.8 h of logging)
    python bench/bench_large_log.py --quick    # 1,000,000 rows (CI)
    python bench/bench_large_log.py --rows N --work DIR --json out.json

The log is SYNTHETIC, made by :func:`make_log` (seed 12, vectorised): a 10 V, 1 s
pulse every 20 s, the thesis dynamic model (``tcamlab.kinds.dynamic.predict`` on the
bundled experiment's sample and rig) evaluated on one 20 s period at 1 kHz and tiled
(the actuator cools to within 0.2% of its rest length before the next pulse), plus
laser noise (sd 5 um) rounded to the logged 1 um. The CSV is cached in ``--work``
(default the system temporary folder) under a name carrying the rows and the seed.

Each measurement runs in a fresh subprocess (wall time and ``ru_maxrss`` of that
process): ``python -m tcamlab validate dynamic`` and ``python -m tcamlab report`` on the
long log, and, in the same run, the straightforward references:

* read: a plain ``pandas.read_csv(path)`` against ``tcamlab.io.read_run``;
* figure: the dynamic figure drawn at full resolution (every row a marker, plain
  matplotlib SVG) against the report's figure (min/max envelope per pixel column).

Nothing asserts on time; each row prints PASS or FAIL against its goal.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
SEED = 12
RATE_HZ = 1000
PERIOD_S = 20.0
NOISE_MM = 0.005
TIME_GOAL_S = 60.0
RSS_GOAL_MB = 4000.0
HTML_GOAL_MB = 5.0
MB = 1e6


def make_log(rows: int, work: Path, seed: int = SEED) -> Path:
    """Write (or reuse) a synthetic experiment of one ``rows``-row 1 kHz dynamic run.

    Returns the experiment TOML's path (``work/biglog-ROWS-sSEED/experiment.toml``).
    """
    import numpy as np
    import pandas as pd

    from tcamlab.config import load_experiment
    from tcamlab.kinds import dynamic

    folder = work / f"biglog-{rows}-s{seed}"
    toml = folder / "experiment.toml"
    if toml.exists():
        return toml
    folder.mkdir(parents=True, exist_ok=True)
    exp = load_experiment(REPO / "experiments" / "dynamic.toml")
    n_period = int(PERIOD_S * RATE_HZ)
    t = np.arange(n_period) / RATE_HZ
    v = np.where((t >= 0.5) & (t < 0.5 + exp.rig.pulse), exp.rig.voltage, 0.0)
    one = dynamic.predict(exp.sample, exp.rig, pd.DataFrame({"time": t, "voltage": v}))
    reps = -(-rows // n_period)
    rng = np.random.default_rng(seed)
    disp_um = np.tile(one["displacement"] * 1e6, reps)[:rows] + rng.normal(0, NOISE_MM * 1e3, rows)
    disp_um = np.round(disp_um).astype(np.int64)
    disp_um[0] = 0  # the log is zeroed on its first row
    ms = np.arange(rows, dtype=np.int64)
    volt = np.tile(v, reps)[:rows]
    # integers written as fixed-point text: much faster than float formatting
    frame = pd.DataFrame(
        {
            "time_s": _fixed(ms, 1000),
            "voltage_V": np.where(volt > 0, "10.000", "0.000"),
            "displacement_mm": _fixed(disp_um, 1000),
        }
    )
    csv = folder / "run1.csv"
    frame.to_csv(csv, index=False, lineterminator="\n")
    src = (REPO / "experiments" / "dynamic.toml").read_text()
    body = src[src.index("[sample]") :]
    toml.write_text(
        'kind = "dynamic"\n'
        f'title = "Long 1 kHz log, {rows} rows (synthetic)"\n'
        'runs = ["run1.csv"]\n'
        'notes = "SYNTHETIC: bench/bench_large_log.py make_log, the thesis model tiled plus noise."\n\n'
        "[synthetic]\n"
        'generator = "bench/bench_large_log.py make_log"\n'
        f"seed = {seed}\n"
        f'command = "python bench/bench_large_log.py --rows {rows}"\n\n' + body
    )
    return toml


def _fixed(values, scale: int):
    """Integers ``values`` / ``scale`` as decimal text with three decimals (scale 1000)."""
    import numpy as np

    sign = np.where(values < 0, "-", "")
    a = np.abs(values)
    whole = (a // scale).astype(str)
    frac = np.char.zfill((a % scale).astype(str), 3)
    return np.char.add(np.char.add(sign, whole), np.char.add(".", frac))
