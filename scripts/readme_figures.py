"""Regenerate the README figures from the bundled (synthetic) sample data.

Run: python scripts/readme_figures.py
Writes docs/img/static_validation.png and docs/img/sensing_validation.png, the
first figure of each validation report, exactly as the reports draw them.
"""

from pathlib import Path

from tcamlab.config import load_experiment
from tcamlab.report.figures import figure_to_png
from tcamlab.report.validation_report import validation_document
from tcamlab.validation import validate

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    out = ROOT / "docs" / "img"
    out.mkdir(parents=True, exist_ok=True)
    for kind in ("static", "sensing"):
        result = validate(load_experiment(ROOT / "experiments" / f"{kind}.toml"))
        doc = validation_document(result)
        figure = doc.sections[1].figures[0].figure
        (out / f"{kind}_validation.png").write_bytes(figure_to_png(figure, dpi=110))


if __name__ == "__main__":
    main()
