"""The calibrated experiment file ``NAME.calibrated.toml``, written beside the original.

It is the original document with each calibrated value replaced (lab units),
its marginal posterior sd in ``[rig.uncertainty]`` / ``[sample.uncertainty]``,
and the joint posterior in a ``[calibration]`` table: the parameter keys, the
coordinates the calibration fits (``log`` for a positive parameter, whose sd is
then relative; ``linear`` otherwise, sd in the key's unit), their sds and
correlation matrix (Laplace, at the MAP point), and the sds below and above the
value from the profile-likelihood 95 % interval (``sd_below``, ``sd_above``:
distance / 1.96; wider than the Laplace sd where the likelihood is skewed). The
dynamic prediction band draws from it (:mod:`tcamlab.band`). The provenance of every value (stated
value, shift in stated sds, profile interval) is a comment block at the top.
Run paths stay valid: the file sits in the original's folder.
"""

from __future__ import annotations

import copy
import math
from pathlib import Path

from tcamlab.config import Experiment, dumps_toml

__all__ = ["calibrated_path", "calibrated_document", "calibrated_text", "joint_table", "SIGNIFICANT"]

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
        "[rig.uncertainty] / [sample.uncertainty]; the joint posterior (sds in the fitted",
        "coordinates and correlations) is in [calibration].",
    ]
    applied = []
    for p in result.parameters:
        if not _applies(p, experiment):
            continue
        lab = (SAMPLE_KEYS if p.where == "sample" else RIG_KEYS)[p.key][1]
        table = doc.setdefault(p.where, {})
        table[p.key] = _round(p.value / lab)
        table.setdefault("uncertainty", {})[p.key] = _round(p.posterior_sd / lab)
        lines.append(_provenance(p, lab))
        applied.append((p, lab))
    doc.pop("calibration", None)
    if applied:
        doc["calibration"] = joint_table(applied, result)
    for fit in getattr(result, "estimator", None) or []:
        if fit.experiment == experiment.name:
            lines += estimator_values(doc, fit)
            joint = refit_joint(doc.get("calibration"), fit)
            if joint:
                doc["calibration"] = joint
    return doc, "\n".join(lines)


ESTIMATOR_KEYS = {
    "initial_resistance": "initial_resistance_ohm",
    "tcr": "tcr_per_K",
    "lead_resistance": "lead_resistance_ohm",
    "stretch_factor": "stretch_factor",
    "tcr2": "tcr2_per_K2",
    "radial_cte": "radial_cte_per_K",
    "youngs_modulus": "youngs_modulus_GPa",
    "damping": "damping_N_s_per_m",
}
"""Key of each field the EKF refit writes: in [sample] for the fields of
:data:`tcamlab.calibration.estimator.SAMPLE_FIELDS`, else in [rig]; in the key's lab unit
(:func:`lab_unit`)."""


def lab_unit(name: str) -> float:
    """SI per lab unit of the key :data:`ESTIMATOR_KEYS` gives field ``name`` (1 but for E's GPa)."""
    from tcamlab.calibration.estimator import SAMPLE_FIELDS
    from tcamlab.params import RIG_KEYS, SAMPLE_KEYS

    return (SAMPLE_KEYS if name in SAMPLE_FIELDS else RIG_KEYS)[ESTIMATOR_KEYS[name]][1]


WRITTEN_SD = ("initial_resistance", "tcr", "tcr2", "radial_cte", "youngs_modulus", "damping")
"""Fields whose EKF-refit sd :func:`estimator_values` writes beside the refitted value."""


def estimator_values(doc: dict, fit) -> list[str]:
    """Write the EKF refit's R0, TCR (and R_lead, k_s, tcr2, b where fitted) into ``doc``'s [rig] and
    its rho and E (where fitted) into [sample]; the header lines that give both fits and which figure
    uses which.

    Raises
    ------
    InputError
        R_lead below 0 or k_s not above 0: loading would refuse the file, so none is written.
    """
    from tcamlab.calibration.estimator import SAMPLE_FIELDS
    from tcamlab.errors import InputError

    if fit.values["lead_resistance"] < 0 or fit.values["stretch_factor"] <= 0:
        raise InputError(
            f"{fit.experiment}: R_lead {fit.values['lead_resistance']:.4g} ohm / k_s "
            f"{fit.values['stretch_factor']:.4g} cannot be written to a calibrated file",
            hint="state lead_resistance_ohm and stretch_factor in [rig]",
        )
    doc.setdefault("rig", {})
    if not fit.fitted:
        return ["Second stage (the estimator's own fit): " + next(iter(fit.held.values()), "not run") + "."]
    lines = [
        "Second stage (the estimator's own fit): R0 and the TCR, with R_lead, k_s, tcr2 and the",
        "mechanics' rho, E and b where the runs identify them, refitted through the causal EKF against the laser ("
        + ", ".join(fit.cases)
        + f"); EKF error rms (rows weighted by the filter's certainty) {fit.rms_before_um:.1f} um -> {fit.rms_after_um:.1f} um.",
    ]
    for name, key in ESTIMATOR_KEYS.items():
        if name not in fit.open_loop:  # a fit from before the field was refitted
            continue
        before, after = fit.open_loop[name], fit.values[name]
        where = "sample" if name in SAMPLE_FIELDS else "rig"
        table = doc.setdefault(where, {})
        lab = lab_unit(name)
        if name in fit.fitted:
            table[key] = _round(after / lab)
            table.setdefault("uncertainty", {})
            # a moved tcr2 with the open-loop stage's sd would not cover its own value
            if name in WRITTEN_SD and _finite(fit.sd.get(name)):
                table["uncertainty"][key] = _round(fit.sd[name] / lab)
            lines.append(
                f"{where}.{key}: open-loop fit {before / lab:.6g}, EKF refit {after / lab:.6g} (written){(getattr(fit, 'disagreements', None) or {}).get(name, '')}"
            )
        else:
            lines.append(
                f"{where}.{key}: {before / lab:.6g}, {fit.held.get(name, 'held at its stated value')}"
            )
    lines += [f"{k}: used by {v}." for k, v in fit.used_by.items()]
    return lines


def _refit_entries(fit) -> list[tuple[str, str]]:
    """(field, ``"where.key"``) of each refitted field written with its refit sd."""
    from tcamlab.calibration.estimator import SAMPLE_FIELDS

    return [
        (n, ("sample." if n in SAMPLE_FIELDS else "rig.") + ESTIMATOR_KEYS[n])
        for n in ESTIMATOR_KEYS
        if n in fit.fitted and n in WRITTEN_SD and _finite(fit.sd.get(n)) and n in fit.open_loop
    ]


def _finite(x) -> bool:
    """Whether a refit's sd or correlation is a number: a singular information matrix gives NaN,
    which the loader refuses; such an entry is left as the open-loop stage wrote it."""
    return x is not None and math.isfinite(float(x))


def refit_joint(joint: dict | None, fit) -> dict | None:
    """The ``[calibration]`` table once the EKF refit has moved some of its fields.

    The open-loop stage's joint posterior describes its own values; where the refit writes
    another value and sd, that entry takes the refit's sd (symmetric: the refit has no
    profile) and the refit's correlations with the other refitted fields. Its correlation
    with a field only the open-loop stage fitted is set to 0: the refit held those fields at
    their open-loop values, so it does not estimate it. The table then agrees with the
    ``[rig.uncertainty]`` / ``[sample.uncertainty]`` sds written beside the values, and the
    block-diagonal matrix stays a correlation matrix.

    Parameters
    ----------
    joint : dict or None
        The open-loop stage's table (:func:`joint_table`), or None when it fitted nothing
        this file holds.
    fit : EstimatorFit
        The refit of this file's experiment.

    Returns
    -------
    dict or None
        The table to write; ``joint`` unchanged when the refit wrote no sd.
    """
    entries = _refit_entries(fit)
    if not entries:
        return joint
    joint = joint or {"parameters": [], "coordinates": [], "sd": [], "correlation": [],
                      "sd_below": [], "sd_above": []}  # fmt: skip
    moved = {key for _, key in entries}
    names = list(joint["parameters"])
    keep = [i for i, key in enumerate(names) if key not in moved]
    # log only where the open-loop stage fitted the log and the refit stayed positive
    coords = [
        "log" if key in names and joint["coordinates"][names.index(key)] == "log" and fit.values[n] > 0
        else "linear"
        for n, key in entries
    ]  # fmt: skip
    sds = [
        fit.sd[n] / abs(fit.values[n]) if c == "log" else fit.sd[n] / lab_unit(n)
        for (n, _), c in zip(entries, coords)
    ]
    refit_names = list(fit.correlation.get("names", []))
    refit_corr = fit.correlation.get("matrix", [])

    def corr(a: str, b: str) -> float:
        if a == b:
            return 1.0
        if a in refit_names and b in refit_names:
            r = float(refit_corr[refit_names.index(a)][refit_names.index(b)])
            return r if _finite(r) else 0.0  # singular data-only information: not estimated
        return 0.0

    n_keep, fields = len(keep), [n for n, _ in entries]
    matrix = [[float(joint["correlation"][i][j]) for j in keep] + [0.0] * len(entries) for i in keep]
    matrix += [[0.0] * n_keep + [corr(a, b) for b in fields] for a in fields]
    out = {
        "parameters": [names[i] for i in keep] + [key for _, key in entries],
        "coordinates": [joint["coordinates"][i] for i in keep] + coords,
        "sd": [joint["sd"][i] for i in keep] + [_round(x) for x in sds],
        "correlation": matrix,
    }
    for side in ("sd_below", "sd_above"):
        if side in joint:
            out[side] = [joint[side][i] for i in keep] + [_round(x) for x in sds]
    return out


def _positive(p, kinds) -> bool:
    """Whether the calibration fitted ``p`` as its logarithm (the kind's CalibrationParam)."""
    from tcamlab.kinds import get_kind

    for kind in kinds:
        for c in get_kind(kind).calibration:
            if (c.field, c.where) == (p.field, p.where):
                return c.positive
    return p.value > 0


def joint_table(applied, result) -> dict:
    """The ``[calibration]`` table of the parameters written to one file.

    Parameters
    ----------
    applied : list of (ParameterEstimate, float)
        The parameters written and their SI per lab unit.
    result : CalibrationResult
        For the correlation matrix (fitted coordinates) and the kinds.

    Returns
    -------
    dict
        ``parameters`` (``"rig.KEY"``), ``coordinates`` (``"log"``/``"linear"``), ``sd``
        (Laplace; relative for log, lab units for linear), ``correlation`` (rows), and
        ``sd_below`` / ``sd_above`` (the profile 95 % interval's distances / 1.96).
    """
    names = result.correlation["names"]
    matrix = result.correlation["matrix"]
    idx = [names.index(p.name) for p, _ in applied]
    logs = [_positive(p, result.kinds) for p, _ in applied]
    sd = [p.posterior_sd_rel if log else p.posterior_sd / lab for (p, lab), log in zip(applied, logs)]
    # full precision: rounded entries can leave a nearly singular matrix indefinite
    corr = [[1.0 if i == j else float(matrix[i][j]) for j in idx] for i in idx]
    below, above = zip(*(_profile_sds(p, lab, log) for (p, lab), log in zip(applied, logs)))
    return {
        "parameters": [f"{p.where}.{p.key}" for p, _ in applied],
        "coordinates": ["log" if log else "linear" for log in logs],
        "sd": [_round(float(x)) for x in sd],
        "correlation": corr,
        "sd_below": [_round(x) for x in below],
        "sd_above": [_round(x) for x in above],
    }


def _profile_sds(p, lab: float, log: bool) -> tuple[float, float]:
    """Sds below and above the value from its profile 95 % interval (distance / 1.96), in the
    fitted coordinate: relative for log, lab units otherwise."""
    from tcamlab.calibration.fit import Z95

    lo, hi = p.profile_95
    if log:
        return math.log(p.value / lo) / Z95, math.log(hi / p.value) / Z95
    return (p.value - lo) / Z95 / lab, (hi - p.value) / Z95 / lab


def calibrated_text(experiment: Experiment, result) -> str:
    """The calibrated experiment file's text (comment header, then the TOML document)."""
    doc, comment = calibrated_document(experiment, result)
    head = "".join(f"# {line}".rstrip() + "\n" for line in comment.splitlines())
    return head + "\n" + dumps_toml(doc)
