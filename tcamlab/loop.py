"""The closed loop on the virtual rig: diagnose, design, measure the designed runs, diagnose.

A benchmark case's first diagnosis runs on its single-protocol runs. :func:`close_loop` asks
:func:`tcamlab.design.design` for the next protocol, writes it as the lab would get it
(``NAME.next.toml``, the runs so far listed), has the virtual rig run it on the same muscle
(:func:`tcamlab.rig.same_truth`: the same effects, true parameters, zeros and scatter, new
noise), and diagnoses every run together. It also reads, from the same design, how a fixed
default protocol (:data:`DEFAULT_PROTOCOL`) would have separated the hypotheses.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from tcamlab.config import load_experiment
from tcamlab.design import DECISIVE, design, protocol_toml
from tcamlab.diagnosis import diagnose
from tcamlab.errors import ConvergenceError, IntegrationError, ModelDomainError
from tcamlab.report.atomic import atomic_write_text
from tcamlab.rig import same_truth, simulate, with_hidden_rig

__all__ = [
    "close_loop",
    "loop_summary",
    "DEFAULT_PROTOCOL",
    "LOOP_SEED_OFFSET",
    "at_least_default",
    "within_reach",
    "reach_sizes",
    "realised_sd",
]

DEFAULT_PROTOCOL = {
    "static": "second load 2x",
    "dynamic": "second voltage 0.8x",
    "sensing": "larger pull range",
    "curvature": "finer levels",
    "selfsensing": "second probe voltage",
}
"""The fixed protocol a lab would run without a design, by kind (a menu entry's name, or the
first entry starting with it): a second load at twice the first, a second voltage, a
second probe voltage."""

LOOP_SEED_OFFSET = 100_000
"""The designed runs' seed is the case's plus this: the same muscle, new noise."""


def close_loop(experiment, first: dict, truth: dict, out_dir, *, seed: int, n_boot: int = 500):
    """(summary, second diagnosis or None) of one turn of the loop.

    Parameters
    ----------
    experiment : tcamlab.config.Experiment
        The simulated experiment the first diagnosis ran on.
    first : dict
        Its diagnosis (:meth:`tcamlab.diagnosis.DiagnosisResult.to_dict`).
    truth : dict
        Its truth file's content (:func:`tcamlab.rig.simulate`).
    out_dir : path-like
        The simulation's folder (gets ``experiments/NAME.next.toml`` and the new runs).
    seed : int
        The case's seed (the designed runs use ``seed +`` :data:`LOOP_SEED_OFFSET`).
    n_boot : int
        Bootstrap resamples of the second diagnosis.

    Returns
    -------
    (dict, dict or None)
        :func:`loop_summary` of the design, and the diagnosis of all runs (None when the
        design proposed nothing: the first diagnosis stands).
    """
    res = design(experiment, first)
    summary = loop_summary(res, experiment.kind)
    if res.best is None:
        return summary, None
    nxt = Path(out_dir) / "experiments" / f"{experiment.name}.next.toml"
    atomic_write_text(nxt, protocol_toml(experiment.raw, res.best.table, res.message))
    name, new_seed = f"{experiment.name}-next", int(seed) + LOOP_SEED_OFFSET
    command = (
        f"tcamlab simulate {experiment.kind} --experiment experiments/{nxt.name} --seed {new_seed} "
        f"--out . --name {name} --truth truth/{experiment.name}.truth.json"
    )
    try:
        sim = simulate(
            experiment.kind,
            with_hidden_rig(load_experiment(nxt, require_runs=False), truth),
            seed=new_seed,
            out_dir=out_dir,
            name=name,
            command=command,
            **same_truth(truth),
        )
    except (ModelDomainError, ConvergenceError, IntegrationError) as exc:
        # The true muscle cannot run the designed protocol (outside the model's domain):
        # recorded, and the first diagnosis stands.
        summary["rig_failed"] = str(exc).split(" (hint")[0]
        return summary, None
    both = load_experiment(sim.experiment_path)
    summary["runs_total"] = len(both.runs)
    second = diagnose(both, n_boot=n_boot, seed=0, workers=1).to_dict()
    summary["realised_sd"] = realised_sd(second, summary["promised_sd"])
    return summary, second


def realised_sd(diagnosis: dict, promised: dict) -> dict:
    """{effect: {parameter: standard error [SI]}} that ``diagnosis`` reports for each parameter
    the design promised an sd of (``promised_sd`` of :func:`loop_summary`), leaving out a
    parameter fitted at a bound (no Laplace interval there)."""
    by = {c["effect"]: c.get("parameters") or {} for c in diagnosis.get("ranking", [])}
    out: dict = {}
    for effect, params in promised.items():
        for n in params:
            p = by.get(effect, {}).get(n) or {}
            if p.get("stderr") and not p.get("at_bound"):
                out.setdefault(effect, {})[n] = float(p["stderr"])
    return out


def _default(res, kind: str):
    name = DEFAULT_PROTOCOL.get(kind, "")
    return next((c for c in res.candidates if c.name == name), None) or next(
        (c for c in res.candidates if name and c.name.startswith(name)), None
    )


def _protocol(c) -> dict | None:
    if c is None:
        return None
    return {
        "protocol": c.name,
        "separation": float(c.separation_refit),
        "beyond_repeat": float(c.beyond_repeat),
        "information_gain": float(c.information_gain),
        "runs": int(c.runs),
        "minutes": float(c.minutes),
        "feasible": bool(c.feasible),
        "decisive": bool(c.decisive),
        "at_fit": {k: float(v) for k, v in c.at_fit.items()},
    }


def loop_summary(res, kind: str) -> dict:
    """What a benchmark keeps of a design: its status, the protocol chosen and the fixed
    default's figures from the same design (separation J, runs), whether the chosen one
    separates at least as well with no more runs (:func:`at_least_default`), and the sd the
    design expects each effect parameter to have after the chosen runs (``promised_sd``
    [SI]; :func:`close_loop` adds the sd the second diagnosis reports, ``realised_sd``)."""
    best, default = _protocol(res.best), _protocol(_default(res, kind))
    return {
        "status": res.status,
        "message": res.message,
        "chosen": best,
        "default": default,
        "at_least_default": at_least_default(best, default),
        "decisive": bool(res.best is not None and res.best.decisive),
        "smallest_detectable": res.smallest_detectable(),
        # the sd the design expects each effect parameter to have once the chosen runs are in
        "promised_sd": {
            h: {n: v / float(np.sqrt(DECISIVE)) for n, v in params.items()}
            for h, params in (res.best.detectable if res.best is not None else {}).items()
        },
    }


def reach_sizes(experiment, first: dict, effect: str, **design_options) -> dict:
    """{parameter: the smallest |value| of ``effect``'s parameters any feasible protocol of the
    menu would tell from zero with the runs so far [SI]}, from a design that weighs the effect
    against recalibration (and any effect the diagnosis left beside the shift) whatever the
    diagnosis's verdict (its fit on the runs so far, as every candidate of the ranking has one).

    A benchmark asks it of a case's true effect where the design did not weigh it (a clear
    first diagnosis, or one whose hypotheses left the truth out), so that whether the menu
    could show the truth (:func:`within_reach`) is known for every case, not only for those
    whose first diagnosis already suspected it. Empty when the effect has no fit in the ranking.
    ``design_options`` go to :func:`tcamlab.design.design`."""
    if not any(c.get("effect") == effect for c in first.get("ranking", [])):
        return {}
    asked = {
        **first,
        "verdict": "miscalibrated",
        "effect": None,
        "aliased_with": [],
        "recalibration": {**(first.get("recalibration") or {}), "stand_ins": {effect: []}},
    }
    return design(experiment, asked, **design_options).smallest_detectable().get(effect, {})


def within_reach(effect: str, true_values: dict, summary: dict) -> bool | None:
    """Whether the design's menu could show ``effect`` at its true parameters [SI]: True when
    sum over its parameters of (true / smallest detectable)^2 >= 1 (the Wald statistic at the
    truth reaches :data:`~tcamlab.design.DECISIVE`; ``smallest_detectable`` of
    :func:`loop_summary`), None when the design did not weigh it (not a hypothesis, or a
    clear first diagnosis)."""
    smallest = (summary.get("smallest_detectable") or {}).get(effect)
    if not smallest:
        return None
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = sum((float(true_values.get(n, 0.0)) / v) ** 2 for n, v in smallest.items() if v > 0)
    return bool(ratio >= 1.0)


def at_least_default(best: dict | None, default: dict | None) -> bool | None:
    """Whether the chosen protocol separates at least as well as the default with no more
    runs: J_chosen >= J_default or the chosen one expected to decide (``decisive``), and
    runs_chosen <= runs_default; True when the default is outside the sample's limits. None when either is missing or the design ranked by precision (a clear
    diagnosis: nothing to separate)."""
    if best is None or default is None:
        return None
    if not default["feasible"]:  # the default would break the sample's limits
        return True
    a, b = best["separation"], default["separation"]
    if not (np.isfinite(a) and np.isfinite(b)):
        return None
    return bool((a >= b or best.get("decisive")) and best["runs"] <= default["runs"])
