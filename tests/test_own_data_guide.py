"""docs/own_data.md really runs: its marked block of shell commands, from a CSV on disk to a
validated, calibrated and diagnosed experiment, run as written in a copy of ``docs/``.

The guide's logs (``docs/own_data/pull*.csv``) are SYNTHETIC: the shipped sensing runs
(``raw/sensing_run*.csv``, ``tcamlab simulate sensing``, seed 1) rewritten in a rheometer's
layout by :func:`rheometer_layout`; a test checks they still are.
"""

from __future__ import annotations

import csv
import hashlib
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
GUIDE = ROOT / "docs" / "own_data.md"
MARK = "<!-- guide-commands: run by tests/test_own_data_guide.py -->"


def rheometer_layout(run_csv: Path, run: int) -> str:
    """A shipped sensing run as a rheometer writes it: a title row, ``Time,Gap,Axial force,R``,
    a units row in brackets, the gap in µm (1000 µm plus the displacement) and tension negative."""
    rows = list(csv.reader(run_csv.open(encoding="utf-8")))
    assert rows[0] == ["time_s", "displacement_mm", "force_N", "resistance_ohm"]
    out = [
        f"Rheometer export - SYNTHETIC: raw/sensing_run{run}.csv (tcamlab simulate sensing seed 1) "
        "in a rheometer's layout",
        "Time,Gap,Axial force,R",
        "[s],[µm],[N],[Ohm]",
    ]
    for t, d, f, r in rows[1:]:
        out.append(f"{float(t):.2f},{1000 + float(d) * 1000:.1f},{-float(f):.6f},{float(r):.3f}")
    return "\n".join(out) + "\n"


def guide_script(text: str) -> str:
    """The bash block right after the marker."""
    m = re.search(re.escape(MARK) + r"\s*```bash\n(.*?)```", text, re.S)
    assert m, f"docs/own_data.md has no ```bash block after {MARK}"
    return m.group(1)


def test_the_guide_logs_are_the_shipped_runs_in_a_rheometer_layout():
    for i in (1, 2, 3):
        shipped = (ROOT / "docs" / "own_data" / f"pull{i}.csv").read_text(encoding="utf-8")
        assert shipped == rheometer_layout(ROOT / "raw" / f"sensing_run{i}.csv", i), i


def test_every_command_the_guide_shows_is_in_its_script():
    """A command shown with its output (``$ tcamlab ...``) or as a bash block is one the
    script runs, except those shown failing (followed by ``error:``)."""
    text = GUIDE.read_text(encoding="utf-8")
    script = guide_script(text)
    shown = re.findall(r"^\$ (tcamlab .*)\n(?!error:)", text, re.M)
    assert len(shown) >= 7
    for command in shown:
        assert command in script, command
    body = text[: text.index(MARK)]
    for block in re.findall(r"```bash\n(.*?)```", body, re.S):
        if "tcamlab init sensing --csv raw/pull1.csv --out" in block or block.startswith(("mkdir", "sed")):
            assert block in script, block


@pytest.fixture
def guide_run(tmp_path_factory):
    """Run the guide's script in a copy of docs/ (the command ``tcamlab`` is this checkout's
    ``python -m tcamlab``); returns (the lab folder, the script's output)."""
    top = tmp_path_factory.mktemp("guide")
    shutil.copytree(ROOT / "docs" / "own_data", top / "docs" / "own_data")
    before = {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in (top / "docs/own_data").iterdir()}
    script = f'set -euo pipefail\ntcamlab() {{ "{sys.executable}" -m tcamlab "$@"; }}\n' + guide_script(
        GUIDE.read_text(encoding="utf-8")
    )
    env = {**os.environ, "PYTHONPATH": str(ROOT), "COLUMNS": "200"}
    proc = subprocess.run(["bash", "-c", script], cwd=top, env=env, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    after = {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in (top / "docs/own_data").iterdir()}
    assert after == before  # the logs are read, never changed
    return top / "mylab", proc.stdout


@pytest.mark.slow
def test_the_guide_walks_a_csv_to_a_validated_calibrated_diagnosed_experiment(guide_run):
    lab, out = guide_run
    # init read the rheometer's layout as the guide says
    assert (
        "displacement_mm  <- 'Gap' [um]" in out and "force_N          <- 'Axial force' [N, scale -1]" in out
    )
    assert "6 values to fill in" in out and "no problems found" in out
    # the glob found the three runs; the µm gap and the negated force are in SI
    metrics = json.loads((lab / "reports/pull/metrics.json").read_text())
    assert [i["path"] for i in metrics["inputs"]] == [
        "../raw/pull1.csv",
        "../raw/pull2.csv",
        "../raw/pull3.csv",
    ]
    pooled = metrics["models"][metrics["primary_model"]]
    assert pooled["displacement_mm"]["pooled"]["r2"] > 0.999 and pooled["force_N"]["pooled"]["r2"] > 0.99
    # the shipped sensor's S is 4.7 N/m (tcamlab/templates/sensing.toml): identified from the logs
    cal = json.loads((lab / "reports/pull/calibration.json").read_text())
    s = next(p for p in cal["parameters"] if p["name"] == "spring_constant")
    assert s["value"] == pytest.approx(4.7, rel=0.01)
    assert (lab / "experiments/pull.calibrated.toml").exists()
    assert "wrote experiments/pull.calibrated.toml\nwrote reports/pull/calibration.json\n" in out
    diagnosis = json.loads((lab / "reports/pull/diagnosis.json").read_text())
    assert diagnosis["verdict"] in ("none", "attributed", "aliased", "miscalibrated")
    for name in ("report.html", "report.pdf", "calibration.html", "diagnosis.html"):
        assert (lab / "reports/pull" / name).stat().st_size > 0, name
