"""The report renders results and computes nothing (docs/architecture.md: ``report/`` at the
top of the layers).

No module of ``tcamlab/report`` takes a function from the layers that compute results
(:data:`COMPUTING`): from them it may import classes (result types, for type hints) and
constants (``Z95``), never a function, and never a module whose functions it could call.
Checked on the source with ``ast`` (lazy imports inside functions too); each imported name
is then looked up to tell a class or a constant from a function.
"""

from __future__ import annotations

import ast
import importlib
import inspect
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
REPORT = ROOT / "tcamlab" / "report"
COMPUTING = ("tcamlab.diagnosis", "tcamlab.calibration", "tcamlab.models")
"""Packages whose functions compute results the report renders."""


def _lower(owner: str) -> bool:
    return any(owner == p or owner.startswith(p + ".") for p in COMPUTING)


def _is_module(dotted: str) -> bool:
    p = ROOT.joinpath(*dotted.split("."))
    return p.with_suffix(".py").is_file() or (p / "__init__.py").is_file()


def _imports(source: str, package: str = "tcamlab.report"):
    """(owner module, imported name or None for ``import owner``, line) of every import."""
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.rsplit(".", node.level - 1)[0] if node.level > 1 else package
                owner = f"{base}.{node.module}" if node.module else base
            else:
                owner = node.module or ""
            for a in node.names:
                yield owner, a.name, node.lineno
        elif isinstance(node, ast.Import):
            for a in node.names:
                yield a.name, None, node.lineno


def _computing_imports(source: str, where: str = "x.py") -> list[str]:
    """``where:line owner.name`` of each function or module taken from :data:`COMPUTING`."""
    bad = []
    for owner, name, line in _imports(source):
        target = owner if name is None else f"{owner}.{name}"
        if not _lower(target):
            continue
        if name is None or _is_module(target):
            bad.append(f"{where}:{line} {target} (a module)")
            continue
        obj = getattr(importlib.import_module(owner), name)
        if inspect.isclass(obj) or not callable(obj):
            continue  # a result type or a constant
        bad.append(f"{where}:{line} {target}")
    return bad


def test_the_detector_sees_every_form():
    src = (
        "from tcamlab.diagnosis.result import DiagnosisResult, stand_ins_text\n"
        "from ..diagnosis.paired import paired_tests\n"
        "from ..calibration.fit import Z95\n"
        "from tcamlab import models\n"
        "import tcamlab.diagnosis.verdict\n"
        "from tcamlab.numbers import fmt\n"
        "def f():\n"
        "    from tcamlab.models.static import displacement\n"
    )
    assert [b.split(" ", 1)[1] for b in _computing_imports(src)] == [
        "tcamlab.diagnosis.result.stand_ins_text",
        "tcamlab.diagnosis.paired.paired_tests",
        "tcamlab.models (a module)",
        "tcamlab.diagnosis.verdict (a module)",
        "tcamlab.models.static.displacement",
    ]


def test_no_report_module_imports_a_function_from_the_computing_layers():
    bad = [
        b
        for path in sorted(REPORT.rglob("*.py"))
        for b in _computing_imports(path.read_text(encoding="utf-8"), str(path.relative_to(ROOT)))
    ]
    assert not bad, "report/ computes nothing: store the value in the result and print it: " + ", ".join(bad)
