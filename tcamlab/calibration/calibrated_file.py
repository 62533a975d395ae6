"""The calibrated experiment file ``NAME.calibrated.toml``, written beside the original.

It is the original document with each calibrated value replaced (lab units) and
its posterior sd in ``[rig.uncertainty]`` / ``[sample.uncertainty]``; the
provenance of every value (stated value, shift in stated sds, profile interval)
is a comment block at the top, since experiment files take no unknown tables.
Run paths stay valid: the file sits in the original's folder.
"""

from __future__ import annotations

import copy
from pathlib import Path

from tcamlab.config import Experiment, dumps_toml

__all__ = ["calibrated_path", "calibrated_document", "calibrated_text", "SIGNIFICANT"]

SIGNIFICANT = 6
"""Significant digits of the values written."""


def calibrated_path(experiment: Experiment) -> Path:
    """``DIR/NAME.calibrated.toml`` beside ``DIR/NAME.toml``."""
    return experiment.path.with_name(experiment.path.stem + ".calibrated.toml")


def _round(x: float) -> float:
    return float(f"{x:.{SIGNIFICANT}g}")


def _applies(p, experiment: Experiment) -> bool:
    return p.where == "sample" or p.name in (p.field, f"{experiment.name}.{p.field}")


def _provenance(p, lab: float) -> str:
    stated = p.stated / lab
    was = (
        f"stated {stated:.4g}"
        if p.stated_in_file
        else f"not stated (prior centred on {stated:.4g}, from the logs)"
    )
    shift = f", {p.shift_in_stated_sds:+.2f} stated sds" if p.shift_in_stated_sds is not None else ""
    lo, hi = (x / lab for x in p.profile_95)
    return (
        f"{p.where}.{p.key} ({p.symbol}): calibrated {p.value / lab:.6g}; {was}{shift}; "
        f"95% profile interval [{lo:.4g}, {hi:.4g}]; sd {p.posterior_sd / lab:.3g}"
    )


def calibrated_document(experiment: Experiment, result) -> tuple[dict, str]:
    """The calibrated TOML document of ``experiment`` and its comment header.

    Parameters
    ----------
    experiment : Experiment
        One of the calibrated experiments.
    result : CalibrationResult
        The calibration.

    Returns
    -------
    (dict, str)
        Document for :func:`tcamlab.config.dumps_toml` and the comment text.
    """
    from tcamlab.params import RIG_KEYS, SAMPLE_KEYS

    doc = copy.deepcopy(experiment.raw)
    lines = [
        f"Calibrated experiment file written by tcamlab calibrate from {experiment.path.name}",
        "(all experiments: " + ", ".join(Path(e).name for e in result.experiments) + ").",
        "Each calibrated value replaces the stated one; its marginal posterior sd (Laplace) is in",
        "[rig.uncertainty] / [sample.uncertainty]; correlations are in calibration.json.",
    ]
    for p in result.parameters:
        if not _applies(p, experiment):
            continue
        lab = (SAMPLE_KEYS if p.where == "sample" else RIG_KEYS)[p.key][1]
        table = doc.setdefault(p.where, {})
        table[p.key] = _round(p.value / lab)
        table.setdefault("uncertainty", {})[p.key] = _round(p.posterior_sd / lab)
        lines.append(_provenance(p, lab))
    return doc, "\n".join(lines)


def calibrated_text(experiment: Experiment, result) -> str:
    """The calibrated experiment file's text (comment header, then the TOML document)."""
    doc, comment = calibrated_document(experiment, result)
    head = "".join(f"# {line}".rstrip() + "\n" for line in comment.splitlines())
    return head + "\n" + dumps_toml(doc)
