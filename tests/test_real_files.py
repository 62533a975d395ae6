"""Regressions found on real files: each test failed on the code before its fix."""

from __future__ import annotations

import json
import shlex
import tomllib
from pathlib import Path

import pytest
from typer.testing import CliRunner

from tcamlab.cli import app

ROOT = Path(__file__).resolve().parents[1]
runner = CliRunner()


def _recorded_commands() -> list[str]:
    """Every tcamlab command recorded in the bundled data (experiment and truth files)."""
    found = set()
    for path in sorted((ROOT / "experiments").glob("*.toml")):
        synthetic = tomllib.loads(path.read_text()).get("synthetic") or {}
        if synthetic.get("command"):
            found.add(synthetic["command"])
    for path in sorted((ROOT / "truth").glob("*.json")):
        found.add(json.loads(path.read_text())["command"])
    return sorted(found)


@pytest.mark.slow
@pytest.mark.parametrize("command", _recorded_commands())
def test_recorded_command_runs_and_remakes_the_shipped_files(tmp_path, monkeypatch, command):
    """The command in each SYNTHETIC banner runs as written and makes the shipped bytes."""
    words = shlex.split(command)
    assert words[0] == "tcamlab"
    monkeypatch.chdir(tmp_path)
    res = runner.invoke(app, words[1:])
    assert res.exit_code == 0, res.output
    made = sorted(p for p in tmp_path.rglob("*") if p.is_file())
    assert made
    for path in made:
        rel = path.relative_to(tmp_path)
        assert path.read_bytes() == (ROOT / rel).read_bytes(), rel
