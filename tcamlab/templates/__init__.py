"""Simulation templates shipped with the package: one experiment file per rig kind.

They hold the sample and rig that ``tcamlab simulate`` and the benchmark take
as the truth; they live inside the package (package data) so an installed
tcamlab finds them without a source checkout.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["TEMPLATES", "template_path", "resolve_template"]

TEMPLATES = Path(__file__).resolve().parent
"""Folder of the shipped templates, ``KIND.toml``."""


def template_path(kind: str) -> Path:
    """The shipped template of a rig kind."""
    return TEMPLATES / f"{kind}.toml"


def resolve_template(name) -> Path:
    """A template given as a path, or as a bare kind ('static') naming a shipped one.

    An existing file always wins, so a user's ./static file is not shadowed.
    """
    path = Path(name)
    if not path.exists() and path.suffix == "" and template_path(str(name)).is_file():
        return template_path(str(name))
    return path
