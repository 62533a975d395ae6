"""The benchmark pages of the documentation are generated from the stored runs
(``scripts/benchmark_page.py``): regenerated here, they equal the committed pages, so a page
cannot drift from its data."""

from __future__ import annotations

import runpy
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_every_stored_run_has_its_page_and_the_pages_are_up_to_date(tmp_path):
    mod = runpy.run_path(str(ROOT / "scripts" / "benchmark_page.py"))
    runs = mod["stored_runs"]()
    assert runs, "no diagnose_<name>_<date>_<commit>.json.gz in bench/reference"
    written = mod["write_pages"](tmp_path)
    assert len(written) == len(runs)
    for page in written:
        committed = ROOT / "docs" / "benchmark" / page.name
        assert committed.exists(), f"{committed} missing: run python scripts/benchmark_page.py"
        assert committed.read_text(encoding="utf-8") == page.read_text(encoding="utf-8"), (
            f"{committed} differs from its data: run python scripts/benchmark_page.py"
        )


def test_a_page_names_its_data_date_and_commit():
    mod = runpy.run_path(str(ROOT / "scripts" / "benchmark_page.py"))
    for path, meta in mod["stored_runs"]():
        text = (ROOT / "docs" / "benchmark" / f"{meta['name']}.md").read_text(encoding="utf-8")
        assert path.name in text and meta["date"] in text and meta["commit"] in text
