"""The tracked text speaks to users about the tool, never about how the work on it was
organised: neither the word for a sitting of work (WORD below, whole word, any case) nor
"issue" followed by a number, in any tracked text file, code comments and docstrings included.
The words are spelled in parts here so that this file passes its own test."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

WORD = "ses" + "sion"
SITTING = re.compile(rf"\b{WORD}\b", re.IGNORECASE)
ISSUE = "iss" + "ue"
ISSUE_NUMBER = re.compile(rf"\b{ISSUE}\s+#?\d+", re.IGNORECASE)

# text that is not ours to reword (the thesis and third-party text, should any be tracked)
EXCLUDED = re.compile(r"(^|/)(tcam-thesis[^/]*|LICENSE[^/]*|third_party/.*|vendor/.*)$")

# files that still cite "issue <number>" and are to be reworded by their owners; the list may
# only shrink: a file that no longer cites one must leave it, and no other file may start to
STILL_CITING_ISSUES = {
    "bench/bench_calibration_coverage.py",
    "bench/bench_selfsensing_calibrated.py",
    "pyproject.toml",
    "tcamlab/benchmark.py",
    "tcamlab/kinds/selfsensing.py",
    "tcamlab/rig/__init__.py",
    "tests/test_bad_input.py",
    "tests/test_calibration.py",
    "tests/test_cli.py",
    "tests/test_hostile_input.py",
    "tests/test_report_honest.py",
    "tests/test_reproducibility.py",
}


def tracked_texts() -> dict[str, str]:
    """Every tracked text file (UTF-8, no NUL byte) by its path, or skip outside a checkout."""
    if shutil.which("git") is None:
        pytest.skip("git is not installed")
    done = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True)
    if done.returncode != 0:
        pytest.skip("not a git checkout")
    texts = {}
    for name in done.stdout.decode("utf-8").split("\0"):
        path = ROOT / name
        if not name or EXCLUDED.search(name) or not path.is_file():
            continue
        data = path.read_bytes()
        if b"\0" in data:
            continue
        try:
            texts[name] = data.decode("utf-8")
        except UnicodeDecodeError:
            continue
    return texts


def _hits(texts: dict[str, str], pattern: re.Pattern) -> dict[str, list[str]]:
    out = {}
    for name, text in texts.items():
        lines = [
            f"{i}: {line.strip()}" for i, line in enumerate(text.splitlines(), 1) if pattern.search(line)
        ]
        if lines:
            out[name] = lines
    return out


def test_no_tracked_text_says_session():
    hits = _hits(tracked_texts(), SITTING)
    assert not hits, f"reword for users (no '{WORD}'):\n" + "\n".join(
        f"{name}:{line}" for name, lines in hits.items() for line in lines
    )


def test_no_tracked_text_cites_an_issue_number():
    hits = _hits(tracked_texts(), ISSUE_NUMBER)
    new = {name: lines for name, lines in hits.items() if name not in STILL_CITING_ISSUES}
    assert not new, "say what the code does, not which issue asked for it:\n" + "\n".join(
        f"{name}:{line}" for name, lines in new.items() for line in lines
    )
    cleaned = sorted(STILL_CITING_ISSUES - set(hits))
    assert not cleaned, f"no longer cite an issue number; remove from STILL_CITING_ISSUES: {cleaned}"


def test_the_patterns_catch_what_they_should():
    assert SITTING.search(f"measured in {WORD.title()} 12") and SITTING.search(f"the {WORD}'s run")
    assert not SITTING.search(f"{WORD}s12 {WORD}less")
    assert ISSUE_NUMBER.search(f"the targets of {ISSUE} 10") and ISSUE_NUMBER.search(f"{ISSUE.title()} #14")
    assert not ISSUE_NUMBER.search(f"an {ISSUE} with 3 runs")
