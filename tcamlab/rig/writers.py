"""What the virtual rig writes: run CSVs, the experiment file and the truth file.

The CSVs and the experiment file look like a lab's (lab units, the kind's
decimals, no trace of the active effects); the truth file keeps everything
the data were made from.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from tcamlab import __version__
from tcamlab import io as tio
from tcamlab.effects import NO_MODS, Mods
from tcamlab.errors import ConfigError
from tcamlab.kinds import get_kind
from tcamlab.params import RIG_KEYS, SAMPLE_KEYS

__all__ = [
    "SYNTHETIC_NOTE",
    "GENERATOR",
    "lab_value",
    "format_csv",
    "experiment_doc",
    "mods_truth",
    "output_paths",
    "refuse_overwrite",
]

# The note names the module file it was written from; it is kept byte for byte
# so that regenerated data (and the shipped sample data) stay identical.
SYNTHETIC_NOTE = (
    "Synthetic data made by the tcamlab virtual rig (tcamlab.rig): the thesis model "
    "evaluated on the exact protocol, then the measurement chains documented in "
    "tcamlab/rig.py. Not a laboratory measurement."
)
"""The ``notes`` of every simulated experiment file."""

GENERATOR = f"tcamlab simulate {__version__}"
"""The generator recorded in experiment and truth files."""


def lab_value(value: float, factor: float) -> float:
    """An SI value in lab units (divided by ``factor``), to 12 significant digits."""
    return float(f"{value / factor:.12g}")


def _lab_entry(value, factor: float):
    return [lab_value(x, factor) for x in value] if isinstance(value, tuple) else lab_value(value, factor)


def format_csv(kind: str, logged: pd.DataFrame) -> str:
    """A run's CSV text: the kind's logged columns in lab units with its decimals.

    Parameters
    ----------
    kind : str
        Rig kind (:attr:`tcamlab.kinds.Kind.logged_columns` present in ``logged``, ``decimals``).
    logged : pandas.DataFrame
        The logged columns [SI, internal names].
    """
    k = get_kind(kind)
    # optional logged columns (a two-condition run's load) are written where the run has them
    canon = tio.internal_to_canonical(logged[[c for c in k.logged_columns if c in logged]])
    cols = []
    for name in canon.columns:
        dec = k.decimals[name]
        # + 0.0 turns -0.0 into 0.0, so no "-0.000" is written.
        vals = np.round(canon[name].to_numpy(float), dec) + 0.0
        cols.append([f"{v:.{dec}f}" for v in vals])
    lines = [",".join(canon.columns)]
    lines += [",".join(row) for row in zip(*cols)]
    return "\n".join(lines) + "\n"


def _sample_table(exp) -> dict[str, Any]:
    table: dict[str, Any] = {}
    if exp.preset:
        table["preset"] = exp.preset
    for key, (si, factor) in SAMPLE_KEYS.items():
        v = getattr(exp.sample, si)
        table[key] = int(v) if key == "thread_plies" else lab_value(v, factor)
    # The stated sds, when the template states any (none: no byte changes).
    unc = getattr(exp, "sample_uncertainty", None) or {}
    si_to_key = {si: (key, factor) for key, (si, factor) in SAMPLE_KEYS.items()}
    if unc:
        table["uncertainty"] = {
            si_to_key[f][0]: lab_value(v, si_to_key[f][1]) for f, v in sorted(unc.items())
        }
    return table


def _rig_table(kind: str, exp) -> dict[str, Any]:
    """The kind's written rig fields and their uncertainties (never the hidden ones), lab units."""
    k = get_kind(kind)
    si_to_key = {si: (key, factor) for key, (si, factor) in RIG_KEYS.items()}
    table: dict[str, Any] = {}
    for fld in k.written_rig_fields:
        v = getattr(exp.rig, fld)
        if v is not None:
            key, factor = si_to_key[fld]
            table[key] = _lab_entry(v, factor)
    unc = {}
    for fld, v in sorted(exp.rig.uncertainty.items()):
        if fld in k.hidden_rig_fields or fld not in si_to_key:
            continue
        key, factor = si_to_key[fld]
        unc[key] = _lab_entry(v, factor)
    if unc:
        table["uncertainty"] = unc
    return table


def experiment_doc(kind: str, exp, run_names: list[str], seed: int, command: str) -> dict[str, Any]:
    """The experiment file's document (TOML tables) for the simulated runs.

    Parameters
    ----------
    kind : str
        Rig kind.
    exp : Experiment
        The template (title, preset, sample, rig, thresholds).
    run_names : list of str
        CSV file names, written as ``../raw/<name>``.
    seed : int
        The simulation seed.
    command : str
        The public command line (without ``--effect``).
    """
    doc: dict[str, Any] = {
        "kind": kind,
        "title": exp.title,
        "runs": [f"../raw/{r}" for r in run_names],
        "notes": SYNTHETIC_NOTE,
        "synthetic": {"generator": GENERATOR, "seed": int(seed), "command": command},
        "sample": _sample_table(exp),
        "rig": _rig_table(kind, exp),
    }
    if exp.thresholds:
        doc["thresholds"] = dict(exp.thresholds)
    return doc


def mods_truth(mods: Mods) -> dict[str, float]:
    """The Mods fields that differ from the thesis model, {field: SI value}."""
    return {f: getattr(mods, f) for f in Mods.__dataclass_fields__ if getattr(mods, f) != getattr(NO_MODS, f)}


def output_paths(out_dir: str | os.PathLike, name: str, n_runs: int) -> list[Path]:
    """Every file a simulation named ``name`` with ``n_runs`` runs writes under ``out_dir``.

    ``raw/<name>_runN.csv``, ``experiments/<name>.toml`` and ``truth/<name>.truth.json``,
    as :func:`tcamlab.rig.simulate` names them.
    """
    out = Path(out_dir)
    runs = [out / "raw" / f"{name}_run{k + 1}.csv" for k in range(n_runs)]
    return runs + [out / "experiments" / f"{name}.toml", out / "truth" / f"{name}.truth.json"]


def refuse_overwrite(paths, *, force: bool = False) -> None:
    """Refuse, before anything is written, to replace files that exist (unless ``force``).

    Raises
    ------
    ConfigError
        Naming every existing file, with the way out (``--force``, another ``--out`` or ``--name``).
    """
    if force:
        return
    existing = [Path(p) for p in paths if Path(p).exists()]
    if existing:
        shown = ", ".join(str(p) for p in existing[:6]) + (
            f" and {len(existing) - 6} more" if len(existing) > 6 else ""
        )
        raise ConfigError(
            f"{len(existing)} file{'s' if len(existing) > 1 else ''} would be overwritten: {shown}",
            "nothing was written; pick another --out or --name, or pass --force to replace them",
        )
