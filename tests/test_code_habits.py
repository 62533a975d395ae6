"""Code habits of the tcamlab package, checked with ``ast`` (no imports of the code).

(a) No function or method longer than MAX_FUNCTION_LINES lines, except the
    named exceptions below, each with its reason.
(b) No private name (leading underscore, not a dunder) taken from another
    tcamlab module: ``from tcamlab.x import _y``, ``from .x import _y``, or
    ``x._y`` where ``x`` is a tcamlab module bound by an import. A private
    *module* used from inside its own package (``tcamlab.models._roots`` by
    ``tcamlab.models.static``) is what the underscore means and is allowed.

Both exception lists must stay honest: an entry whose function no longer
exists or is no longer long, or an import that is gone, fails the test so
the entry is removed with the fix.
"""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent.parent / "tcamlab"
MAX_FUNCTION_LINES = 80


DOCSTRING = "within the limit without its numpy docstring (parameters with units, equations)"

LONG_FUNCTIONS: dict[str, str] = {
    "tcamlab.fitting:fit_spring": DOCSTRING,
    "tcamlab.io:column_spec": DOCSTRING,
    "tcamlab.models._roots:bracketed_newton": DOCSTRING,
    "tcamlab.models.dynamic:response": DOCSTRING,
    "tcamlab.models.dynamic:monte_carlo": DOCSTRING,
    "tcamlab.rig:simulate": DOCSTRING,
    "tcamlab.benchmark:run_benchmark": DOCSTRING,
    "tcamlab.cli:simulate": "a Typer command: its 12 options are declared in the signature (6 lines each)",
    "tcamlab.models.sensing:invert": DOCSTRING,
    "tcamlab.models.static:displacement": DOCSTRING,
}
"""module:qualified name -> why it may stay longer than MAX_FUNCTION_LINES."""

PRIVATE_IMPORTS: dict[str, str] = {}
"""importing module -> owning module.name -> why it is still imported."""


def _modules():
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE.parent).with_suffix("")
        parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
        yield ".".join(parts), path, ast.parse(path.read_text(encoding="utf-8"), filename=str(path))


def _is_package(path: Path) -> bool:
    return path.name == "__init__.py"


def _functions(tree):
    """(qualified name, lines) of every function and method, nested ones too."""

    def walk(node, prefix):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                name = prefix + child.name
                yield name, child.end_lineno - child.lineno + 1
                yield from walk(child, name + ".")
            elif isinstance(child, ast.ClassDef):
                yield from walk(child, prefix + child.name + ".")
            else:
                yield from walk(child, prefix)

    yield from walk(tree, "")


def _long_functions() -> dict[str, int]:
    return {
        f"{mod}:{name}": n
        for mod, _, tree in _modules()
        for name, n in _functions(tree)
        if n > MAX_FUNCTION_LINES
    }


def _is_module(dotted: str) -> bool:
    p = PACKAGE.parent.joinpath(*dotted.split("."))
    return p.with_suffix(".py").is_file() or (p / "__init__.py").is_file()


def _private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def _parent(dotted: str) -> str:
    return dotted.rpartition(".")[0]


def _private_uses(mod: str, path: Path, tree) -> set[str]:
    """'mod -> owner.name' for each private name this module takes from another tcamlab module."""
    package = mod if _is_package(path) else _parent(mod)
    aliases: dict[str, str] = {}  # local name -> tcamlab module it is bound to
    found: set[str] = set()

    def take(owner: str, name: str) -> None:
        if owner == mod or not _private(name):
            return
        target = f"{owner}.{name}"
        if _is_module(target) and mod.startswith(owner + "."):
            return  # a private module of the importer's own package
        found.add(f"{mod} -> {target}")

    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.rsplit(".", node.level - 1)[0] if node.level > 1 else package
                owner = f"{base}.{node.module}" if node.module else base
            else:
                owner = node.module or ""
            if not owner.startswith("tcamlab"):
                continue
            for a in node.names:
                take(owner, a.name)
                if _is_module(f"{owner}.{a.name}"):
                    aliases[a.asname or a.name] = f"{owner}.{a.name}"
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.startswith("tcamlab."):
                    take(_parent(a.name), a.name.rpartition(".")[2])
                if a.name.split(".")[0] == "tcamlab":
                    aliases[a.asname or "tcamlab"] = a.name if a.asname else "tcamlab"
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and _private(node.attr):
            dotted = _dotted(node.value)
            if dotted is None:
                continue
            head, _, rest = dotted.partition(".")
            if head in aliases:
                owner = aliases[head] + ("." + rest if rest else "")
                if _is_module(owner):
                    take(owner, node.attr)
    return found


def _dotted(node) -> str | None:
    if isinstance(node, ast.Name):
        return node.id
    if isinstance(node, ast.Attribute):
        inner = _dotted(node.value)
        return None if inner is None else f"{inner}.{node.attr}"
    return None


def _all_private_uses() -> set[str]:
    return {use for mod, path, tree in _modules() for use in _private_uses(mod, path, tree)}


# --- (a) function length -------------------------------------------------------------


def test_the_walk_sees_the_package():
    names = {f"{mod}:{name}" for mod, _, tree in _modules() for name, _ in _functions(tree)}
    # a module-level function, a method and a function in a subpackage
    assert "tcamlab.kinds:predict" in names
    assert "tcamlab.diagnosis.problem:Problem.norm_resid" in names
    assert "tcamlab.models.static:displacement" in names


def test_no_function_longer_than_the_limit():
    long = _long_functions()
    new = {k: v for k, v in long.items() if k not in LONG_FUNCTIONS}
    assert not new, (
        f"functions over {MAX_FUNCTION_LINES} lines: "
        + ", ".join(f"{k} ({v} lines)" for k, v in sorted(new.items()))
        + "; split them (or, with a reason, add them to LONG_FUNCTIONS)"
    )


def test_long_function_exceptions_are_still_needed():
    long = _long_functions()
    stale = sorted(k for k in LONG_FUNCTIONS if k not in long)
    assert not stale, f"no longer long or gone, remove from LONG_FUNCTIONS: {', '.join(stale)}"
    assert all(reason.strip() for reason in LONG_FUNCTIONS.values())


# --- (b) private names across modules ---------------------------------------------------


def test_private_use_detector_sees_every_form():
    src = (
        "from tcamlab.io import _a\n"
        "from .metrics import _b, ok\n"
        "from tcamlab import effects as fw\n"
        "import tcamlab.models.static\n"
        "from . import __version__\n"
        "from tcamlab.x import _own\n"
        "def f():\n"
        "    return fw._c, tcamlab.models.static._d, fw.ok\n"
    )
    found = _private_uses("tcamlab.x", PACKAGE / "x.py", ast.parse(src))
    assert found == {
        "tcamlab.x -> tcamlab.io._a",
        "tcamlab.x -> tcamlab.metrics._b",
        "tcamlab.x -> tcamlab.effects._c",
        "tcamlab.x -> tcamlab.models.static._d",
    }
    # a private module of the importer's own package is allowed; of another is not
    ok = "from tcamlab.models import _roots\nfrom . import _static_kernel\n"
    assert _private_uses("tcamlab.models.static", PACKAGE / "models" / "static.py", ast.parse(ok)) == set()
    bad = "from tcamlab.models import _roots\n"
    assert _private_uses("tcamlab.rig", PACKAGE / "rig.py", ast.parse(bad)) == {
        "tcamlab.rig -> tcamlab.models._roots"
    }


def test_no_private_names_across_modules():
    new = sorted(_all_private_uses() - set(PRIVATE_IMPORTS))
    assert not new, (
        "private names used from another tcamlab module: "
        + ", ".join(new)
        + "; make them public (or, with a reason, add them to PRIVATE_IMPORTS)"
    )


def test_private_import_exceptions_are_still_needed():
    stale = sorted(set(PRIVATE_IMPORTS) - _all_private_uses())
    assert not stale, f"no longer used, remove from PRIVATE_IMPORTS: {', '.join(stale)}"
