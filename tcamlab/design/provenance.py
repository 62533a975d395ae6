"""Whether a stored diagnosis is one of the experiment a design is asked for.

A ``diagnosis.json`` records the experiment file it was made of (its path from the working
folder, its name and sha256) and each run's sha256 (``experiment.inputs``). A design from
another experiment's diagnosis, or from one made before runs were added or changed, would
separate hypotheses the runs no longer leave, under the wrong sample and rig.
"""

from __future__ import annotations

import json
from pathlib import Path

from tcamlab.errors import ConfigError
from tcamlab.io import sha256_file
from tcamlab.text import shown_path

__all__ = ["check_diagnosis_file"]


def _sha(path) -> str | None:
    """SHA-256 of a file's bytes, None where it cannot be read."""
    try:
        return sha256_file(path)
    except OSError:
        return None


def _same_experiment(record: dict, experiment) -> bool:
    """Whether ``record`` (a diagnosis's ``experiment``) names ``experiment``: the same bytes,
    else the same file from the working folder, else (a path that does not resolve here) the
    same name."""
    inputs = record.get("inputs") or []
    sha = [i.get("sha256") for i in inputs if i.get("role") == "experiment"]
    if sha and sha[0] == _sha(experiment.path):
        return True
    path = record.get("path")
    if isinstance(path, str) and path and not path.startswith(".../") and Path(path).is_file():
        return Path(path).resolve() == Path(experiment.path).resolve()
    return record.get("name") in (None, experiment.name)


def _hints(experiment, force: bool) -> str:
    """The commands that diagnose ``experiment`` and design from that diagnosis."""
    exp = shown_path(experiment.path)
    again = " --force" if force else ""
    return (
        f"diagnose it first: tcamlab diagnose {exp} --out reports{again}, then "
        f"tcamlab design {exp} --diagnosis reports/{experiment.name}/diagnosis.json"
    )


def check_diagnosis_file(experiment, path) -> None:
    """Refuse a stored diagnosis made of another experiment, or of runs that differ from the
    experiment's now (added, removed or changed since). A file that is not JSON, or records
    no experiment (written by hand), is left to the reader of the diagnosis.

    Parameters
    ----------
    experiment : tcamlab.config.Experiment
        The experiment to design for.
    path : path-like
        Its ``diagnosis.json``.

    Raises
    ------
    ConfigError
        Naming both files, with the commands that diagnose this experiment first.
    """
    try:
        doc = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return
    record = doc.get("experiment") if isinstance(doc, dict) else None
    if not isinstance(record, dict):
        return
    diag, exp = shown_path(path), shown_path(experiment.path)
    if not _same_experiment(record, experiment):
        made_of = record.get("path") or record.get("name") or "another experiment"
        raise ConfigError(f"{diag}: a diagnosis of {made_of}, not of {exp}", _hints(experiment, False))
    then = sorted(str(i.get("sha256")) for i in record.get("inputs") or [] if i.get("role") == "run")
    if not then:
        return
    now = sorted(str(_sha(p)) for p in experiment.runs)
    if then != now:
        new = len(set(now) - set(then))
        raise ConfigError(
            f"{diag}: made of {len(then)} runs of {exp}, which lists {len(now)} now "
            f"({new} added or changed since)",
            _hints(experiment, True),
        )
