"""Nothing lost, atomic writes, idempotence.

- raw/ is never written: every file's hash is the same before and after each command;
- a report is written all or nothing: a killed process or a failing renderer/file system
  leaves neither half-written outputs nor temporary files, and an older report stays intact;
- outputs are byte-identical run to run, with any SOURCE_DATE_EPOCH (nothing embeds a date),
  and carry no absolute paths.
"""

from __future__ import annotations

import hashlib
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from typer.testing import CliRunner

from tcamlab import kinds
from tcamlab.cli import app

ROOT = Path(__file__).resolve().parents[1]
runner = CliRunner()
KINDS = kinds.KINDS
OUTPUTS = ("report.html", "report.pdf", "metrics.json", "predictions.csv")


def tree_hashes(folder: Path) -> dict[str, tuple[str, int]]:
    """Relative path -> (sha256, mode) of every file below folder."""
    return {
        str(p.relative_to(folder)): (hashlib.sha256(p.read_bytes()).hexdigest(), p.stat().st_mode)
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


def leftovers(folder: Path) -> list[Path]:
    return [p for p in folder.rglob("*") if p.name.endswith(".tmp") or p.name.startswith(".")]


# --- nothing lost ----------------------------------------------------------------------


COMMANDS = {
    **{
        f"validate-{k}": ["validate", k, f"experiments/{k}.toml", "--out", "out", "--mc-draws", "20"]
        for k in KINDS
    },
    "validate-drop-na": [
        "validate",
        "static",
        "experiments/static.toml",
        "--out",
        "out",
        "--drop-na",
        "--format",
        "html",
    ],
    "validate-bad-kind": ["validate", "sensing", "experiments/static.toml", "--out", "out"],
    "report": ["report", "--out", "out", "--mc-draws", "20"],
    "fit-spring": [
        "fit-spring",
        "raw/sensing_run1.csv",
        "raw/sensing_run2.csv",
        "experiments/sensing.toml",
        "--plot",
        "out/fit.svg",
        "--json",
    ],
    "fit-spring-bad": ["fit-spring", "raw/static_run1.csv"],
}


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_no_command_writes_to_raw_or_experiments(lab, monkeypatch, name):
    monkeypatch.chdir(lab)
    before_raw, before_exp = tree_hashes(lab / "raw"), tree_hashes(lab / "experiments")
    result = runner.invoke(app, COMMANDS[name])
    assert result.exit_code == (2 if name.endswith("bad") or name.endswith("bad-kind") else 0), result.output
    assert tree_hashes(lab / "raw") == before_raw
    assert tree_hashes(lab / "experiments") == before_exp
    assert sorted(p.name for p in (lab / "raw").iterdir()) == sorted(p.split("/")[-1] for p in before_raw)


# --- atomic writes -------------------------------------------------------------------------


def test_killed_validate_leaves_no_partial_report_and_no_temp_files(lab):
    """SIGKILL a long dynamic validation part way; then the folder holds either
    nothing new or the old complete report, never a fragment or a temp file."""
    out = lab / "out"
    # an older, complete report of the same experiment must survive untouched
    ok = runner.invoke(
        app,
        ["validate", "dynamic", str(lab / "experiments/dynamic.toml"), "--out", str(out), "--mc-draws", "10"],
    )
    assert ok.exit_code == 0, ok.output
    old = tree_hashes(out)
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "tcamlab",
            "validate",
            "dynamic",
            "experiments/dynamic.toml",
            "--out",
            "out",
            "--mc-draws",
            "20000",
            "--force",
        ],
        cwd=lab,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
    )
    try:
        time.sleep(3.0)
        assert proc.poll() is None, "validation finished before it could be killed"
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=30)
    finally:
        if proc.poll() is None:  # pragma: no cover
            proc.kill()
            proc.wait()
    assert proc.returncode == -signal.SIGKILL
    assert tree_hashes(out) == old
    assert leftovers(out) == []


def _validate_in_process(lab: Path, out: Path):
    from tcamlab.pipeline import validate_experiment

    return validate_experiment(lab / "experiments/static.toml", out, force=True)


def test_renderer_failing_mid_run_writes_nothing(lab, monkeypatch):
    import tcamlab.report.pdf as pdf

    def boom(doc):
        raise RuntimeError("renderer crashed")

    monkeypatch.setattr(pdf, "render_pdf", boom)
    out = lab / "out"
    with pytest.raises(RuntimeError):
        _validate_in_process(lab, out)
    assert not (out / "static").exists() or list((out / "static").iterdir()) == []


def test_failure_while_writing_keeps_the_old_report_whole(lab, monkeypatch):
    """The disk fills up while the third of four files is written: the report folder
    must still hold the previous complete report (old code replaced files one by one)."""
    from tcamlab.errors import TcamlabError

    out = lab / "out"
    _validate_in_process(lab, out)
    old = tree_hashes(out)
    # a new report would differ from the old one
    exp = lab / "experiments/static.toml"
    exp.write_text(exp.read_text().replace("load_g = 50.0", "load_g = 51.0"))
    calls = {"n": 0}
    real_fsync = os.fsync

    def flaky_fsync(fd):
        calls["n"] += 1
        if calls["n"] == 3:
            raise OSError(28, "No space left on device")
        return real_fsync(fd)

    monkeypatch.setattr(os, "fsync", flaky_fsync)
    with pytest.raises(TcamlabError) as info:
        _validate_in_process(lab, out)
    assert "No space left on device" in info.value.one_line()
    monkeypatch.setattr(os, "fsync", real_fsync)
    assert tree_hashes(out) == old
    assert leftovers(out) == []


# --- idempotence ---------------------------------------------------------------------------


def _all_outputs(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _run_everything(lab: Path, out: str) -> dict[str, bytes]:
    for args in (
        ["report", "--out", out, "--mc-draws", "30"],
        ["fit-spring", "raw/sensing_run1.csv", "raw/sensing_run2.csv", "--plot", f"{out}/fit.svg", "--force"],
        ["fit-spring", "raw/sensing_run1.csv", "--plot", f"{out}/fit.png", "--force"],
        [
            "validate",
            "dynamic",
            "experiments/dynamic.toml",
            "--out",
            f"{out}/v",
            "--mc-draws",
            "30",
            "--force",
        ],
    ):
        result = runner.invoke(app, args)
        assert result.exit_code == 0, result.output
    return _all_outputs(lab / out)


@pytest.mark.slow
def test_outputs_are_byte_identical_and_ignore_source_date_epoch(lab, monkeypatch):
    monkeypatch.chdir(lab)
    monkeypatch.delenv("SOURCE_DATE_EPOCH", raising=False)
    first = _run_everything(lab, "a")
    suffixes = {Path(n).suffix for n in first}
    assert {".html", ".pdf", ".json", ".csv", ".svg", ".png"} <= suffixes
    assert _run_everything(lab, "a") == first  # same folder, rewritten
    assert _run_everything(lab, "b") == first  # another folder: nothing says where
    for epoch in ("1", "2000000000"):
        monkeypatch.setenv("SOURCE_DATE_EPOCH", epoch)
        assert _run_everything(lab, "a") == first, f"SOURCE_DATE_EPOCH={epoch} changed a byte"


@pytest.mark.slow
def test_outputs_hold_no_absolute_paths(lab, tmp_path_factory):
    """Run with absolute paths from another working directory, as a user would."""
    elsewhere = tmp_path_factory.mktemp("cwd")
    out = lab / "out"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    for args in (
        ["validate", "static", str(lab / "experiments/static.toml"), "--out", str(out)],
        [
            "report",
            str(lab / "experiments/sensing.toml"),
            str(lab / "experiments/curvature.toml"),
            "--out",
            str(out),
        ],
        ["fit-spring", str(lab / "raw/sensing_run1.csv"), "--plot", str(out / "fit.svg")],
    ):
        proc = subprocess.run(
            [sys.executable, "-m", "tcamlab", *args], cwd=elsewhere, env=env, capture_output=True, text=True
        )
        assert proc.returncode == 0, proc.stderr
    from pypdf import PdfReader

    needles = {str(lab), str(elsewhere), str(ROOT)}
    files = [p for p in out.rglob("*") if p.is_file()]
    assert len(files) >= 10
    for p in files:
        data = p.read_bytes()
        text = data.decode("latin-1")
        if p.suffix == ".pdf":
            text += "".join(page.extract_text() for page in PdfReader(str(p)).pages)
        for needle in needles:
            assert needle not in text, f"{needle} in {p.relative_to(out)}"
    html = (out / "static/report.html").read_text()
    assert "tcamlab validate static .../static.toml" in html
