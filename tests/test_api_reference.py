"""The generated API reference names every public module of the library."""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "tcamlab"
NOT_LIBRARY = {"tcamlab.cli", "tcamlab.__main__", "tcamlab.templates"}
"""The command line (its own generated reference, docs/cli.md) and data, not an API."""


def _public_modules() -> set[str]:
    names = set()
    for path in PACKAGE.rglob("*.py"):
        rel = path.relative_to(ROOT).with_suffix("")
        parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
        if any(p.startswith("_") for p in parts):
            continue
        names.add(".".join(parts))
    return names - NOT_LIBRARY - {"tcamlab"}


def test_every_public_module_has_a_directive_in_the_api_reference():
    pages = "\n".join(p.read_text() for p in (ROOT / "docs" / "api").glob("*.md"))
    missing = sorted(m for m in _public_modules() if f"::: {m}\n" not in pages + "\n")
    assert not missing, f"add to docs/api/ (and mkdocs.yml): {missing}"


def test_every_api_page_is_in_the_site_menu():
    menu = (ROOT / "mkdocs.yml").read_text()
    pages = sorted(p.name for p in (ROOT / "docs" / "api").glob("*.md"))
    assert pages and all(f"api/{name}" in menu for name in pages)
