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
SITTING = re.compile(rf"(?<![a-z]){WORD}(\b|[-_]?\d)", re.IGNORECASE)
ISSUE = "iss" + "ue"
ISSUE_NUMBER = re.compile(rf"\b{ISSUE}\s+#?\d+", re.IGNORECASE)

# text that is not ours to reword (the thesis and third-party text, should any be tracked)
EXCLUDED = re.compile(r"(^|/)(tcam-thesis[^/]*|LICENSE[^/]*|third_party/.*|vendor/.*)$")


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


def test_no_tracked_text_says_the_word():
    hits = _hits(tracked_texts(), SITTING)
    assert not hits, f"reword for users (no '{WORD}'):\n" + "\n".join(
        f"{name}:{line}" for name, lines in hits.items() for line in lines
    )


def test_no_tracked_text_cites_an_issue_number():
    hits = _hits(tracked_texts(), ISSUE_NUMBER)
    assert not hits, "say what the code does, not which issue asked for it:\n" + "\n".join(
        f"{name}:{line}" for name, lines in hits.items() for line in lines
    )


def test_no_tracked_file_name_says_the_word():
    named = [name for name in tracked_texts() if SITTING.search(name)]
    assert not named, f"rename (by date and commit, not by {WORD}): {named}"


def test_the_patterns_catch_what_they_should():
    assert SITTING.search(f"measured in {WORD.title()} 12") and SITTING.search(f"the {WORD}'s run")
    assert SITTING.search(f"rescored_{WORD}12.md") and SITTING.search(f"the {WORD}-20 run")
    assert not SITTING.search(f"{WORD}s {WORD}less")
    assert ISSUE_NUMBER.search(f"the targets of {ISSUE} 10") and ISSUE_NUMBER.search(f"{ISSUE.title()} #14")
    assert not ISSUE_NUMBER.search(f"an {ISSUE} with 3 runs")
