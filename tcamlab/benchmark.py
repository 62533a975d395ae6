"""Withheld-effect benchmark of the gap diagnosis (:mod:`tcamlab.diagnosis`).

For every effect of every rig kind, at strengths 1, 3 and 10 (multiples of
the noise RMS), the virtual rig (:func:`tcamlab.rig.simulate`) makes data
*with* the effect; :func:`tcamlab.diagnosis.diagnose` then sees only the
experiment file and the logs and has to name the effect. Null cases (no
effect) measure false attributions; pairs of effects check that two causes
are reported as aliased or as one of the pair, never as a confident third.

Only the benchmark reads the simulator's truth files (to score); the
diagnosis never does.

With ``lies=True`` the rig also lies like a real lab: null cases whose true
parameters are drawn within their stated uncertainty (parameter error F =
:data:`LIE_PARAMETER_ERROR`; the stated sds are the template's and the kind's
:attr:`~tcamlab.kinds.Kind.benchmark_uncertainty`) and whose runs start from noisy zeros. They are
scored apart (``null_miscalibrated``): every confident verdict on them is a
false attribution, physics blamed for a wrong parameter or zero.

Five more families (:data:`FAMILIES`, :func:`family_tasks`) keep the benchmark from being
the diagnosis's mirror: ``calibration-only`` (no effect, stated parameters 1-3 stated sds
off), ``realistic`` (an effect, parameters drawn within their stated sds, noisy zeros),
``off-library`` (each effect in a form outside the library, :mod:`tcamlab.rig.offlibrary`,
which the diagnosis never imports), ``null-noisy-zero`` and ``null-quiet`` (the same with a
fifth of the instruments' noise); their files state
:data:`STATED_UNCERTAINTY`. :func:`family_scores` scores each against its target and
:func:`plan_full_run` costs the full run from a run's per-case times.

Each kind sets its cases' protocol options and effect pairs (:attr:`tcamlab.kinds.Kind.benchmark_program`,
:attr:`~tcamlab.kinds.Kind.benchmark_pairs`); static cases use the heat-cool oven.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
import time
from collections import Counter, defaultdict
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from tcamlab.effects import effects_for, get_effect
from tcamlab.jsonutil import dumps_json, to_jsonable
from tcamlab.kinds import KINDS, get_kind
from tcamlab.report.atomic import write_all_or_nothing
from tcamlab.templates import template_path

__all__ = [
    "STRENGTHS",
    "BenchmarkResult",
    "run_benchmark",
    "run_task",
    "execute_tasks",
    "GENERATOR",
    "KINDS",
    "make_tasks",
    "score",
    "noise_ceiling",
    "LIE_PARAMETER_ERROR",
    "lying_null_task",
    "FAMILIES",
    "CASE_FAMILY",
    "STATED_UNCERTAINTY",
    "family_tasks",
    "family_scores",
    "calibration_offsets",
    "stated_template",
    "stated_uncertainty",
    "true_effect",
    "right",
    "right_candidate",
    "names_its_parameter",
    "named_or_aliased",
    "separable",
    "SEPARABLE_RATIO",
    "plan_full_run",
]

STRENGTHS = (1.0, 3.0, 10.0)
"""Effect strengths, multiples of the noise RMS."""

PAIR_STRENGTH = 5.0


LIE_PARAMETER_ERROR = 1.0
"""F of the lying null cases: true parameters drawn with the stated sd (:mod:`tcamlab.rig.lies`)."""

GENERATOR = "tcamlab.rig"
"""The simulator the benchmark's cases come from (recorded in every result)."""


BENCHMARK_KINDS = tuple(k for k in KINDS if k != "selfsensing")
"""Kinds the benchmark runs unless told otherwise: selfsensing's virtual rig integrates a
50 s powered run per simulation (about 4 s), too slow for the benchmark's budget while its
diagnosis is not a target; pass ``kinds`` to include it."""


# ---------------------------------------------------------------------------
# tasks
# ---------------------------------------------------------------------------


FAMILIES = (
    "effect-only",
    "null",
    "calibration-only",
    "realistic",
    "off-library",
    "null-noisy-zero",
    "null-quiet",
)
"""Families of cases: the effect-only cases (singles and, in the full run, pairs), the
null cases, and the families of a lab that lies (:func:`family_tasks`)."""

CASE_FAMILY = {
    "single": "effect-only",
    "pair": "effect-only",
    "null": "null",
    "null-miscalibrated": "null",
    "calibration-only": "calibration-only",
    "realistic": "realistic",
    "off-library": "off-library",
    "null-noisy-zero": "null-noisy-zero",
    "null-quiet": "null-quiet",
}
"""The family of each task ``case``."""

FAMILY_STRENGTHS = (3.0, 10.0)
"""Strengths of the realistic and out-of-library families (their targets are at 3x and 10x)."""

FAMILY_SEEDS = {
    "calibration-only": 7000,
    "realistic": 8000,
    "off-library": 8500,
    "null-noisy-zero": 5500,
    "null-quiet": 5600,
}
"""First seed of each lying family."""

CALIBRATION_OFFSET_SD = (1.0, 3.0)
"""|offset| of a calibration-only case's perturbed parameters, in stated sds (uniform)."""

QUIET_NOISE_SCALE = 0.2
"""Instrument noise of the ``null-quiet`` family, in multiples of the rig's (quantisation
steps unchanged): the 10-bit laser ADC's 9.8 um step then carries 1 um of noise."""

NULL_FAMILIES = ("null", "null-noisy-zero", "null-quiet")
"""Families without an effect, scored by false attributions and ``none``."""

MIN_POSITIVE_SHARE = 0.3
"""A positive parameter is moved down only while it keeps this share of its stated value
(else up): C_th -3 sds would be 5 % of its stated value, a different actuator."""

STATED_UNCERTAINTY: dict[str, dict[str, dict[str, float]]] = {
    "static": {
        "rig": {},
        "sample": {"radial_cte": 8.1e-6, "youngs_modulus": 0.1725e9, "shear_modulus_slope": 0.222e6},
    },
    "dynamic": {
        "rig": {"thermal_mass": 0.00845, "heat_loss": 0.0027, "damping": 0.12},
        "sample": {"radial_cte": 8.1e-6, "shear_modulus_slope": 0.222e6},
    },
    "sensing": {"rig": {}, "sample": {"youngs_modulus": 0.345e9}},
    "curvature": {"rig": {"sensor_offset": 0.3e-3}, "sample": {"youngs_modulus": 0.345e9}},
}
"""Stated sds [SI] of the lying families' experiment files ([rig.uncertainty],
[sample.uncertainty]): the thesis's C_th 0.0266 +- 0.00845 J/K and b 0.84 +- 0.12 N s/m;
lambda 0.00893 +- 0.0027 W/K (30 %, where the thesis's 0.01615 puts a third of the
mass below zero); rho 10 %, E 5 % (static; 10 % sensing and curvature), G_t slope 20 %,
d1 0.3 mm."""


def make_tasks(
    *,
    quick: bool = False,
    seeds: int = 10,
    kinds=None,
    effects=None,
    lies: bool = False,
    families=("effect-only", "null"),
    conditions: int = 1,
    templates=None,
) -> list[dict]:
    """Task dicts (case, kind, effects {name: strength}, seed).

    ``templates`` ({kind: experiment file}) benchmarks another sample or rig: that kind's
    cases simulate from the file's sample, rig and protocol instead of the bundled template,
    and the lying families state the same relative uncertainty (:func:`stated_uncertainty`).

    ``conditions`` 2 makes every case a two-condition experiment (its runs alternate between
    the stated condition and the kind's second, :data:`tcamlab.rig.CONDITIONS`: the
    experiment each aliased verdict names); only kinds that have a second condition run.

    ``families`` (:data:`FAMILIES`) picks the families; the default is the
    effect-only and null cases of the earlier benchmark. ``lies`` adds, per
    kind and seed (6000 on), a ``null-miscalibrated`` case: no effect, true
    parameters drawn within their stated uncertainty and noisy zeros
    (:func:`lying_null_task`). The other families: :func:`family_tasks`.
    """
    families = tuple(families)
    unknown = sorted(set(families) - set(FAMILIES))
    if unknown:
        from tcamlab.errors import ConfigError

        raise ConfigError(f"unknown benchmark family {unknown[0]!r}", hint="families: " + ", ".join(FAMILIES))
    tasks = []
    kinds = _condition_kinds(kinds, conditions)
    strengths = (3.0,) if quick else STRENGTHS
    n_seeds = min(2, max(int(seeds), 1)) if quick else max(int(seeds), 1)
    for kind in kinds:
        names = [e.name for e in effects_for(kind)]
        if effects is not None:
            names = [n for n in names if n in effects]
        if "effect-only" in families:
            for name in names:
                for s in strengths:
                    for seed in range(n_seeds):
                        tasks.append(
                            {"case": "single", "kind": kind, "effects": {name: s}, "seed": 1000 + seed}
                        )
        if "null" in families:
            for seed in range(n_seeds):
                tasks.append({"case": "null", "kind": kind, "effects": {}, "seed": 5000 + seed})
        if lies:
            tasks += [lying_null_task(kind, 6000 + seed) for seed in range(n_seeds)]
        if not quick and "effect-only" in families:
            for a, b in get_kind(kind).benchmark_pairs:
                for seed in range(max(3, n_seeds // 2)):
                    tasks.append(
                        {
                            "case": "pair",
                            "kind": kind,
                            "effects": {a: PAIR_STRENGTH, b: PAIR_STRENGTH},
                            "seed": 9000 + seed,
                        }
                    )
        template = (templates or {}).get(kind)
        tasks += family_tasks(kind, families, quick=quick, seeds=seeds, effects=effects, template=template)
    tasks = [
        {**t, "template": str(templates[t["kind"]])} if t["kind"] in (templates or {}) else t for t in tasks
    ]
    return [{**t, "conditions": conditions} for t in tasks] if conditions != 1 else tasks


def loop_tasks(tasks: list[dict], quick: bool) -> list[dict]:
    """The closed loop's tasks: the cases of kinds with a protocol menu, single effects at
    :data:`FAMILY_STRENGTHS` (its targets' strengths; no pairs), each marked ``closed_loop``;
    quick: the first case of each family and kind."""
    from tcamlab.design.protocols import kind_module

    out, seen = [], set()
    for t in tasks:
        if not hasattr(kind_module(t["kind"]), "design_menu") or t["case"] == "pair":
            continue
        if t["case"] == "single" and _strength(t) < min(FAMILY_STRENGTHS):
            continue
        key = (t["kind"], CASE_FAMILY.get(t["case"], t["case"]))
        if quick and key in seen:
            continue
        seen.add(key)
        out.append({**t, "closed_loop": True})
    return out


def _condition_kinds(kinds, conditions: int) -> tuple:
    """The kinds a benchmark of ``conditions`` runs (two: those with a second condition)."""
    from tcamlab.errors import ConfigError
    from tcamlab.rig import CONDITIONS

    if conditions not in (1, 2):
        raise ConfigError(f"conditions must be 1 or 2, got {conditions!r}")
    if conditions == 1:
        return tuple(BENCHMARK_KINDS if kinds is None else kinds)
    if kinds is None:
        return tuple(k for k in BENCHMARK_KINDS if k in CONDITIONS)
    lacking = [k for k in kinds if k not in CONDITIONS]
    if lacking:
        raise ConfigError(
            f"the {lacking[0]} rig has no second condition",
            hint="--conditions 2 runs " + ", ".join(f"{k} ({v})" for k, v in CONDITIONS.items()),
        )
    return tuple(kinds)


def family_seeds(quick: bool, seeds: int) -> int:
    """Seeds per (effect or form, strength) cell of the realistic and out-of-library families:
    1 in the quick run, else ``ceil(seeds / 5)`` (their cells are many; the full run must
    stay plannable)."""
    return 1 if quick else max(1, math.ceil(int(seeds) / 5))


def family_tasks(
    kind: str, families, *, quick: bool = False, seeds: int = 10, effects=None, template=None
) -> list[dict]:
    """The lying families' tasks of one kind.

    - ``calibration-only``: no effect; one or two stated parameters exactly 1-3
      stated sds off (:func:`calibration_offsets`); ``seeds`` cases.
    - ``realistic``: each effect at 3x and 10x with the parameters drawn within their
      stated sds (F = 1) and noisy zeros.
    - ``off-library``: each form of :mod:`tcamlab.rig.offlibrary` at 3x and 10x.
    - ``null-noisy-zero``: no effect, noisy zeros; ``seeds`` cases.
    - ``null-quiet``: as ``null-noisy-zero`` with a fifth of the instruments' noise
      (:data:`QUIET_NOISE_SCALE`; their quantisation steps stay): quiet instruments on
      coarse converters, the re-mounting scatter above the noise.

    Every case states :data:`STATED_UNCERTAINTY` (scaled to ``template``'s values when given:
    :func:`stated_uncertainty`). The quick run has one case of each family per kind (the
    first effect or form, at 3x).
    """
    from tcamlab.rig.offlibrary import forms_for

    n = family_seeds(quick, seeds)
    n_null = 1 if quick else max(int(seeds), 1)
    strengths = (3.0,) if quick else FAMILY_STRENGTHS
    stated = {"stated": stated_uncertainty(kind, template)}
    names = [e.name for e in effects_for(kind) if effects is None or e.name in effects]
    forms = [f for f in forms_for(kind) if effects is None or f.nearest in effects]
    if quick:
        names, forms = names[:1], forms[:1]
    out = []
    for fam in (f for f in families if f in FAMILY_SEEDS):  # effect-only and null: make_tasks
        case = {"case": fam, "kind": kind, "effects": {}, **stated}
        seeds_of = [FAMILY_SEEDS[fam] + i for i in range(n_null if fam in _NULL_LIKE else n)]
        if fam == "calibration-only":
            out += [
                {**case, "seed": s, "parameter_offsets": calibration_offsets(kind, s, template)}
                for s in seeds_of
            ]
        elif fam in ("null-noisy-zero", "null-quiet"):
            quiet = {"noise_scale": QUIET_NOISE_SCALE} if fam == "null-quiet" else {}
            out += [{**case, "seed": s, "noisy_zero": True, **quiet} for s in seeds_of]
        elif fam == "realistic":
            lies = {"parameter_error": 1.0, "noisy_zero": True}
            out += [
                {**case, "effects": {e: st}, "seed": s, **lies}
                for e in names
                for st in strengths
                for s in seeds_of
            ]
        elif fam == "off-library":
            out += [
                {**case, "offlibrary": {f.name: st}, "nearest": f.nearest, "seed": s}
                for f in forms
                for st in strengths
                for s in seeds_of
            ]
    return out


_NULL_LIKE = ("calibration-only", "null-noisy-zero", "null-quiet")
"""Families of one case per seed (the others: one per effect or form, strength and seed)."""


def stated_uncertainty(kind: str, template=None) -> dict[str, dict[str, float]]:
    """The lying families' stated sds [SI] (:data:`STATED_UNCERTAINTY`) for ``template``
    (an experiment file of the kind; default the bundled one): the same *relative* sds of
    that sample's and rig's values, so another sample is benchmarked under the same stated
    uncertainty (rho 10 %, E 5-10 %, ...)."""
    st = STATED_UNCERTAINTY[kind]
    if template is None:
        return st
    from tcamlab.config import load_experiment

    ref = load_experiment(template_path(kind), require_runs=False)
    exp = load_experiment(template, require_runs=False)
    out = {}
    for table in ("rig", "sample"):
        a, b = getattr(ref, table), getattr(exp, table)
        out[table] = {f: sd * _ratio(getattr(b, f), getattr(a, f)) for f, sd in st[table].items()}
    return out


def _ratio(value, reference) -> float:
    """|value / reference|, 1 where either is unset or zero (the sd then stays absolute)."""
    if value is None or reference is None or not reference or not value:
        return 1.0
    return abs(float(value) / float(reference))


def stated_template(kind: str, template=None):
    """The kind's template experiment (or ``template``'s) with the lying families' stated sds
    (:func:`stated_uncertainty`) in it."""
    import dataclasses

    from tcamlab.config import load_experiment

    exp = load_experiment(template or template_path(kind), require_runs=False)
    st = stated_uncertainty(kind, template)
    rig = exp.rig.replace(uncertainty={**exp.rig.uncertainty, **st["rig"]})
    return dataclasses.replace(exp, rig=rig, sample_uncertainty={**exp.sample_uncertainty, **st["sample"]})


def calibration_offsets(kind: str, seed: int, template=None) -> dict[str, float]:
    """{field: offset in stated sds} of a calibration-only case: one or two of the stated
    parameters, |offset| uniform in :data:`CALIBRATION_OFFSET_SD`, random sign (up where
    down would leave a positive parameter under :data:`MIN_POSITIVE_SHARE` of its value)."""
    exp = stated_template(kind, template)
    st = stated_uncertainty(kind, template)
    fields = sorted(st["rig"]) + sorted(st["sample"])
    rng = np.random.default_rng([int(seed), 0xCA1])
    k = int(rng.integers(1, min(2, len(fields)) + 1))
    out = {}
    for fld in sorted(rng.choice(fields, size=k, replace=False)):
        sd = {**st["rig"], **st["sample"]}[fld]
        stated = getattr(exp.rig if fld in st["rig"] else exp.sample, fld)
        d = float(rng.uniform(*CALIBRATION_OFFSET_SD)) * (1.0 if rng.random() < 0.5 else -1.0)
        if d < 0 and stated > 0 and stated + d * sd < MIN_POSITIVE_SHARE * stated:
            d = -d
        out[str(fld)] = d
    return out


def lying_null_task(kind: str, seed: int) -> dict:
    """A null case of a lab that lies: parameters F = 1 stated sd off, noisy zeros, no effect."""
    return {
        "case": "null-miscalibrated",
        "kind": kind,
        "effects": {},
        "seed": int(seed),
        "parameter_error": LIE_PARAMETER_ERROR,
        "noisy_zero": True,
        "uncertainty": dict(get_kind(kind).benchmark_uncertainty),
    }


def _program(kind: str, task: dict) -> dict:
    """The kind's benchmark protocol options, overridden by those the task sets."""
    k = get_kind(kind)
    return {**k.benchmark_program, **{o: task[o] for o in k.program_options if o in task}}


def _outside_domain(exc: Exception) -> bool:
    from tcamlab.errors import ConvergenceError, IntegrationError, ModelDomainError

    return isinstance(exc, (ModelDomainError, ConvergenceError, IntegrationError))


def _simulate_case(kind: str, template, task: dict, tmp: str, extra: dict):
    """Simulate one case: ``(SimulationResult, flipped offsets or None)``.

    A calibration-only draw whose truth the model cannot run on the rig's protocol
    (static: a G(T) slope 1.2 stated sds up puts G_t' of (2.13) <= 0 below the oven's
    130 K rise) is a muscle that does not exist, so it is drawn on the other side of the
    stated value, as :data:`MIN_POSITIVE_SHARE` does for parameters near zero.
    """
    from tcamlab.errors import ModelDomainError
    from tcamlab.rig import simulate

    def run(lies):
        return simulate(kind, template, seed=task["seed"], out_dir=tmp, effects=dict(task["effects"]), **lies)

    try:
        return run(extra), None
    except ModelDomainError:
        if not task.get("parameter_offsets"):
            raise
    flipped = {k: -float(v) for k, v in task["parameter_offsets"].items()}
    return run({**extra, "parameter_offsets": flipped}), flipped


def run_task(task: dict) -> dict:
    """Simulate one case in its own temp dir, diagnose it, score against the truth file.

    ``task`` holds ``case``, ``kind``, ``effects`` {name: strength} and
    ``seed``; optional ``template`` (experiment file; default the kind's
    template), ``noise_scale``, ``oven`` (static) and the rig's lies
    (``parameter_error``, ``noisy_zero``, ``uncertainty``) go to the
    simulator, ``n_boot`` to the diagnosis.
    """
    from tcamlab.config import load_experiment
    from tcamlab.diagnosis import diagnose

    kind = task["kind"]
    t0 = time.perf_counter()
    out = dict(task)
    out["generator"] = GENERATOR
    stage = "setup"
    with tempfile.TemporaryDirectory(prefix="tcam-bench-") as tmp:
        try:
            if "stated" in task:
                template = stated_template(kind, task.get("template"))
            else:
                template = task.get("template") or template_path(kind)
            extra = _program(kind, task)
            if "noise_scale" in task:
                extra["noise_scale"] = float(task["noise_scale"])
            lies = (
                "parameter_error",
                "noisy_zero",
                "uncertainty",
                "parameter_offsets",
                "offlibrary",
                "conditions",
            )
            extra.update({k: task[k] for k in lies if k in task})
            stage = "simulate"  # a drawn truth the model cannot run is no diagnosis error
            sim, flipped = _simulate_case(kind, template, task, tmp, extra)
            if flipped:
                out["parameter_offsets"], out["offsets_flipped"] = flipped, True
            stage = "diagnose"
            truth = json.loads(Path(sim.truth_path).read_text())
            exp = load_experiment(sim.experiment_path)
            res = diagnose(exp, n_boot=task.get("n_boot", 500), seed=0, workers=1)
            if task.get("closed_loop"):
                from tcamlab.loop import close_loop

                stage = "loop"
                first = res.to_dict()
                loop, second = close_loop(
                    exp, first, truth, tmp, seed=task["seed"], n_boot=task.get("n_boot", 500)
                )
                loop.update(_truth_reach(exp, first, task, loop))
                out["loop"] = loop
                out["after"] = _digest(second, truth, kind, task) if second is not None else None
        except Exception as exc:  # a failed case is recorded, not fatal
            out.update(
                {
                    "error": f"{type(exc).__name__}: {exc}",
                    # only a truth outside the model's domain is skipped; any other failure counts
                    "error_stage": stage if stage != "simulate" or _outside_domain(exc) else "simulate-other",
                    "seconds": time.perf_counter() - t0,
                }
            )
            return out
    out.update(_digest(res.to_dict(), truth, kind, task))
    out["seconds"] = time.perf_counter() - t0
    return out


def _truth_reach(exp, first: dict, task: dict, loop: dict) -> dict:
    """``{"truth_reach": {effect: {parameter: smallest detectable [SI]}}}`` for a case's single
    true effect (not an off-library form) that the design did not weigh
    (:func:`tcamlab.loop.reach_sizes`), so that :func:`_reach` knows for every case whether
    the menu could show the truth; empty otherwise."""
    from tcamlab.loop import reach_sizes

    effects = list(task.get("effects") or {})
    if len(effects) != 1 or task.get("nearest") or effects[0] in (loop.get("smallest_detectable") or {}):
        return {}
    return {"truth_reach": {effects[0]: reach_sizes(exp, first, effects[0])}}


def _digest(d: dict, truth: dict, kind: str, task: dict) -> dict:
    """What the scores need of a diagnosis (``d``: ``DiagnosisResult.to_dict()``) and its truth."""
    return {
        "verdict": d["verdict"],
        "effect": d["effect"],
        "aliased_with": d["aliased_with"],
        "recalibrated": (d.get("recalibration") or {}).get("named", []),
        "recalibrated_aliases": sorted(
            {a for v in ((d.get("recalibration") or {}).get("aliased_parameters") or {}).values() for a in v}
        ),
        "ranking": [c["effect"] for c in d["ranking"]],
        "shrinkage": {c["effect"]: c["shrinkage"] for c in d["ranking"]},
        "fraction_closed": {c["effect"]: c["fraction_closed"] for c in d["ranking"]},
        "gap_rmse_over_noise": d["gap"]["rmse_over_noise"],
        "gap_limit": d["gap"]["limit"],
        "heldout_rmse_before_noise": (d["ranking"][0]["heldout_rmse_before_noise"] if d["ranking"] else None),
        "fitted": {c["effect"]: {k: v["value"] for k, v in c["parameters"].items()} for c in d["ranking"]},
        "truth_values": _truth_values(truth, kind, task["effects"]),
        **_lies_values(truth),
        **({"offlibrary_truth": truth["offlibrary"]} if "offlibrary" in truth else {}),
    }


def _lies_values(truth: dict) -> dict:
    """The rig's lies from a truth file: {parameter: offset in stated sds} and each run's zero errors."""
    out = {}
    if "true_parameters" in truth:
        out["parameter_offsets_sd"] = {f: v["offset_sd"] for f, v in truth["true_parameters"].items()}
    if truth.get("noisy_zero"):
        out["zero_errors"] = [r.get("zero_error", {}) for r in truth["runs"]]
    return out


def _truth_values(truth: dict, kind: str, effects: dict) -> dict:
    """{effect: {field: true value}} from a :func:`tcamlab.rig.simulate` truth file."""
    out = {}
    for name in effects:
        params = truth["effects"][name]["parameters"]
        fields = get_effect(name, kind).param_names
        out[name] = {
            f: (float(params[f]) if isinstance(params[f], (int, float)) else params[f])
            for f in fields
            if f in params
        }
    return out


# ---------------------------------------------------------------------------
# scoring
# ---------------------------------------------------------------------------

CONFIDENT = ("attributed", "aliased")


def _label(r: dict) -> str:
    if "error" in r:
        return "error"
    if r["verdict"] in CONFIDENT:
        return r["effect"]
    return r["verdict"]


def true_effect(r: dict) -> str:
    """The effect a right diagnosis names: the nearest library effect of an out-of-library
    form, else the case's (first) effect; ``none (null)`` without one."""
    if r.get("nearest"):
        return r["nearest"]
    return next(iter(r["effects"])) if r["effects"] else "none (null)"


def _named(r: dict) -> set[str]:
    """The parameters a ``miscalibrated`` verdict names (SI field names)."""
    return {n.rpartition(".")[2] for n in r.get("recalibrated") or []}


def names_its_parameter(r: dict) -> bool:
    """``miscalibrated`` naming a parameter whose error the true effect's term *is*
    (:attr:`tcamlab.effects.Effect.generalises`: the sensor-to-cable distance error and the
    calibrated d1; the sensor's ambient offset and R0). The two are one physical fact in two
    words, and naming the parameter with its value and interval is the right diagnosis."""
    truth = true_effect(r)
    if "error" in r or r.get("verdict") != "miscalibrated" or truth == "none (null)":
        return False
    try:
        own = set(get_effect(truth, r["kind"]).generalises)
    except Exception:  # an unknown name (a pair, a retired effect) has no parameter of its own
        return False
    return bool(own & _named(r))


def right(r: dict) -> bool:
    """Top-1 right: the true effect named (``attributed`` or first of ``aliased``), or the
    parameter whose error it is recalibrated (:func:`names_its_parameter`)."""
    if "error" in r:
        return False
    return (r["verdict"] in CONFIDENT and r["effect"] == true_effect(r)) or names_its_parameter(r)


def right_candidate(r: dict) -> str:
    """The candidate behind a right diagnosis (whose shrinkage and parameters are scored)."""
    return "recalibration" if names_its_parameter(r) else true_effect(r)


def named_or_aliased(r: dict) -> bool:
    """The true effect named (top-1), or, under ``miscalibrated`` or ``aliased``, listed among
    what the data cannot tell apart from the verdict (``aliased_with``): an honest answer on
    one condition, where a recalibration fits the withheld runs as well as the effect."""
    if "error" in r:
        return False
    truth = true_effect(r)
    if right(r):
        return True
    return r["verdict"] in ("miscalibrated", "aliased") and truth in (r.get("aliased_with") or [])


SEPARABLE_RATIO = 1.02
"""A case is *separable* on its withheld runs when recalibration's held-out RMSE is at least
this factor above the true effect's (each fitted with the recalibrated parameters). Below it
no rule scored on withheld runs can prefer the effect: on the 2026-11-24 full run the
`miscalibrated` misses had a median ratio of 1.000 (``bench/analyse_benchmark.py``)."""


def separable(r: dict) -> bool:
    """Whether the true effect beats recalibration on the withheld runs (:data:`SEPARABLE_RATIO`)."""
    sh = r.get("shrinkage") or {}
    t, recal = sh.get(true_effect(r)), sh.get("recalibration")
    if "error" in r or t is None or recal is None or not (t < 1 and np.isfinite(t) and np.isfinite(recal)):
        return False
    return (1.0 - recal) / (1.0 - t) >= SEPARABLE_RATIO


def points_to_truth(r: dict) -> bool:
    """Whether the withheld runs themselves point to the true effect: it beats recalibration
    (:func:`separable`) and no other candidate fits them better (held-out RMSE, each fitted
    with the recalibrated parameters). An out-of-library form's data can lie nearer another
    library effect than its own: a tilted curvature sensor (d1 error a on the tip, a / 3 on the
    base) is fitted by axial compression to 100 % of its gap and by the sensor-offset error to
    93 %, and no rule scored on those runs can name the offset."""
    sh = r.get("shrinkage") or {}
    t = sh.get(true_effect(r))
    if not separable(r):
        return False
    return all(not (np.isfinite(v) and v > t) for k, v in sh.items() if k != true_effect(r))


def _acc(rows: list[dict]) -> dict:
    """Top-1 / top-3 accuracy of single-effect cases (an error counts as wrong), the share
    named or honestly aliased (:func:`named_or_aliased`), and top-1 on the cases where the true
    effect beats recalibration on the withheld runs (:func:`separable`)."""
    n = len(rows)
    if not n:
        return {"n": 0, "top1": None, "top3": None, "named_or_aliased": None}
    sep = [r for r in rows if separable(r)]
    best = [r for r in rows if points_to_truth(r)]
    top1 = top3 = 0
    for r in rows:
        truth = true_effect(r)
        if "error" in r:
            continue
        conf = r["verdict"] in CONFIDENT
        # the named effect (the best single candidate, or the primary of a pair), or the
        # parameter whose error the effect is
        top1 += int(right(r))
        top3 += int(right(r) or (conf and truth in r["ranking"][:3]))
    honest = sum(named_or_aliased(r) for r in rows)
    return {
        "n": n,
        "top1": top1 / n,
        "top3": top3 / n,
        "named_or_aliased": honest / n,
        "separable_n": len(sep),
        "separable_top1": sum(right(r) for r in sep) / len(sep) if sep else None,
        "points_n": len(best),
        "points_right": sum(right(r) for r in best),
    }


def _strength(r: dict) -> float:
    return next(iter({**r["effects"], **r.get("offlibrary", {})}.values()))


def _accuracy(singles: list[dict]) -> dict:
    """Accuracy by strength, by kind, by kind and strength, and by effect."""
    strengths = sorted({_strength(r) for r in singles})
    by_kind = {
        k: _acc([r for r in singles if r["kind"] == k]) for k in KINDS if any(r["kind"] == k for r in singles)
    }
    by_effect: dict[str, list] = {}
    for r in singles:
        by_effect.setdefault(f"{r['kind']}/{next(iter(r['effects']))}", []).append(r)
    return {
        "accuracy_by_strength": {str(s): _acc([r for r in singles if _strength(r) == s]) for s in strengths},
        "accuracy_by_kind": by_kind,
        "accuracy_by_kind_and_strength": {
            k: {str(s): _acc([r for r in singles if r["kind"] == k and _strength(r) == s]) for s in strengths}
            for k in by_kind
        },
        "accuracy_by_effect": {k: _acc(v) for k, v in sorted(by_effect.items())},
    }


def _right_cases(singles: list[dict]):
    """Shrinkage per strength cell and parameter recovery of the right attributions."""
    shrink, recov = [], defaultdict(list)
    by_s = defaultdict(lambda: {"shrinkage": [], "attainable": [], "fraction_closed": []})
    for r in singles:
        if not right(r):
            continue
        truth, cand = true_effect(r), right_candidate(r)
        shrink.append(r["shrinkage"][cand])
        cell = by_s[str(_strength(r))]
        cell["shrinkage"].append(r["shrinkage"][cand])
        cell["fraction_closed"].append(r.get("fraction_closed", {}).get(cand))
        b4 = r.get("heldout_rmse_before_noise")
        if b4 and b4 > 1.0:
            # On withheld data no model beats the noise (RMSE/noise = 1), so a case
            # can shrink by at most 1 - 1/b4.
            cell["attainable"].append(r["shrinkage"][cand] / (1.0 - 1.0 / b4))
        tv = r.get("truth_values", {}).get(truth, {})
        fv = r.get("fitted", {}).get(cand, {})
        for f, v in tv.items():
            if f in fv and isinstance(v, float) and v != 0 and fv[f] is not None:
                recov[f"{r['kind']}/{truth}"].append(abs(fv[f] - v) / abs(v))
    return shrink, recov, by_s


RIGHT_ON_MISCALIBRATED_NULL = ("none", "miscalibrated")
"""Verdicts that are right on a null case whose parameters are off (no effect): within noise,
or the gap closed by recalibration. ``miscalibrated`` on an effect case is a miss."""


def _null_summary(nulls: list[dict]) -> dict:
    """False attributions of null cases; the right verdicts and the miscalibrated ones that
    name a parameter the rig truly moved (for the lying nulls)."""
    null_false = [r for r in nulls if "error" not in r and r["verdict"] in CONFIDENT]
    right = [r for r in nulls if "error" not in r and r["verdict"] in RIGHT_ON_MISCALIBRATED_NULL]
    named_true = [
        r
        for r in nulls
        if r.get("verdict") == "miscalibrated"
        and set(r.get("recalibrated", [])) & set(r.get("parameter_offsets_sd", {}))
    ]
    by_kind = {
        k: {
            "n": sum(r["kind"] == k for r in nulls),
            "false": sum(r["kind"] == k for r in null_false),
            "verdicts": dict(Counter(r.get("verdict", "error") for r in nulls if r["kind"] == k)),
        }
        for k in KINDS
        if any(r["kind"] == k for r in nulls)
    }
    return {
        "n": len(nulls),
        "false_attributions": len(null_false),
        "rate": (len(null_false) / len(nulls)) if nulls else None,
        "right": len(right),
        "miscalibrated_naming_a_moved_parameter": len(named_true),
        "by_kind": by_kind,
    }


def _pair_outcome(r: dict) -> str:
    names = list(r["effects"])
    if "error" in r:
        return "error"
    if r["verdict"] == "aliased" and set(names) & ({r["effect"]} | set(r["aliased_with"])):
        return "aliased"
    if r["verdict"] in CONFIDENT and r["effect"] in names:
        return "one of the pair"
    if r["verdict"] in CONFIDENT:
        return "confident third effect (failure)"
    return r["verdict"]


def _pair_row(r: dict) -> dict:
    return {
        "kind": r["kind"],
        "pair": " + ".join(r["effects"]),
        "seed": r["seed"],
        "verdict": r.get("verdict"),
        "effect": r.get("effect"),
        "aliased_with": r.get("aliased_with"),
        "outcome": _pair_outcome(r),
    }


def _confusion(rows: list[dict]) -> dict[str, dict[str, dict[str, int]]]:
    confusion: dict[str, dict[str, dict[str, int]]] = {}
    for r in rows:
        truth = true_effect(r)
        if r.get("offlibrary"):
            truth = f"{next(iter(r['offlibrary']))} ({truth})"
        cell = confusion.setdefault(r["kind"], {}).setdefault(truth, {})
        lab = _label(r)
        cell[lab] = cell.get(lab, 0) + 1
    return confusion


def _moved(r: dict) -> set[str]:
    """The parameters the rig truly moved (an exact offset or a draw off the stated value)."""
    return {f for f, d in (r.get("parameter_offsets_sd") or {}).items() if d}


def _named_moved(r: dict) -> bool:
    return r.get("verdict") == "miscalibrated" and bool(_named(r) & _moved(r))


def _named_or_partner_moved(r: dict) -> bool:
    """``miscalibrated`` naming a moved parameter, or one the verdict says the data fix only
    together with a named one (``aliased_parameters``)."""
    partners = {n.rpartition(".")[2] for n in r.get("recalibrated_aliases") or []}
    return r.get("verdict") == "miscalibrated" and bool((_named(r) | partners) & _moved(r))


def _rate(k: int, n: int):
    return k / n if n else None


def _calibration_only(rows: list[dict]) -> dict:
    """Calibration-only cases: attributed to an effect (target <= 5 %) and `miscalibrated`
    naming a parameter the rig truly moved (target >= 80 %)."""
    ok = [r for r in rows if "error" not in r]
    attributed = sum(r["verdict"] == "attributed" for r in ok)
    confident = sum(r["verdict"] in CONFIDENT for r in ok)
    named = sum(_named_moved(r) for r in ok)
    with_partners = sum(_named_or_partner_moved(r) for r in ok)
    return {
        "n": len(rows),
        "attributed": attributed,
        "attributed_rate": _rate(attributed, len(rows)),
        "attributed_or_aliased_rate": _rate(confident, len(rows)),
        "miscalibrated_naming_a_moved_parameter": named,
        "miscalibrated_right_rate": _rate(named, len(rows)),
        "miscalibrated_right_or_partner_rate": _rate(with_partners, len(rows)),
        "verdicts": dict(Counter(r.get("verdict", "error") for r in rows)),
    }


def _noisy_nulls(rows: list[dict]) -> dict:
    """Null cases: false attributions (target <= 5 %) and `none` (target >= 90 %)."""
    false = sum(r.get("verdict") in CONFIDENT for r in rows)
    none = sum(r.get("verdict") == "none" for r in rows)
    return {
        "n": len(rows),
        "false_attributions": false,
        "false_rate": _rate(false, len(rows)),
        "none": none,
        "none_rate": _rate(none, len(rows)),
        "verdicts": dict(Counter(r.get("verdict", "error") for r in rows)),
    }


def family_scores(results: list[dict]) -> dict:
    """Per family: the figures its targets are stated in (README)."""
    by = defaultdict(list)
    for r in results:
        by[CASE_FAMILY.get(r["case"], r["case"])].append(r)
    out = {}
    singles = [r for r in by.get("effect-only", []) if r["case"] == "single"]
    if singles:
        out["effect-only"] = {
            str(s): _acc([r for r in singles if _strength(r) == s])
            for s in sorted({_strength(r) for r in singles})
        }
    for fam in ("realistic", "off-library"):
        rows = by.get(fam, [])
        if rows:
            out[fam] = {
                str(s): _acc([r for r in rows if _strength(r) == s])
                for s in sorted({_strength(r) for r in rows})
            }
    if by.get("calibration-only"):
        out["calibration-only"] = _calibration_only(by["calibration-only"])
    for fam in NULL_FAMILIES:
        rows = [r for r in by.get(fam, []) if r["case"] != "null-miscalibrated"]
        if rows:
            out[fam] = _noisy_nulls(rows)
    return out


def _family_confusion(results: list[dict]) -> dict:
    """{family: {kind: {truth: {diagnosis: n}}}} of the lying families."""
    out = {}
    for fam in ("calibration-only", "realistic", "off-library", "null-noisy-zero", "null-quiet"):
        rows = [r for r in results if r["case"] == fam]
        if rows:
            out[fam] = _confusion(rows)
    return out


def score(results: list[dict]) -> dict:
    """Accuracy tables, false attributions, shrinkage, recovery, pairs, confusion, families.

    A case whose virtual rig could not run its drawn truth (``error_stage == "simulate"``,
    e.g. a G_t slope drawn so steep that G_t' of (2.13) turns non-positive inside the oven
    program) is left out of every rate and listed under ``skipped``: it is not a diagnosis."""
    skipped = [r for r in results if r.get("error_stage") == "simulate"]
    results = [r for r in results if r.get("error_stage") != "simulate"]
    singles = [r for r in results if r["case"] == "single"]
    nulls = [r for r in results if r["case"] == "null"]
    lying = [r for r in results if r["case"] == "null-miscalibrated"]
    shrink, recov, by_s = _right_cases(singles)
    pair_rows = [_pair_row(r) for r in results if r["case"] == "pair"]
    return {
        **({"null_miscalibrated": _null_summary(lying)} if lying else {}),
        **_accuracy(singles),
        "null": _null_summary(nulls),
        "median_shrinkage_when_right": float(np.median(shrink)) if shrink else None,
        "shrinkage_by_strength": {
            k: _shrink_cell(k, v) for k, v in sorted(by_s.items(), key=lambda kv: float(kv[0]))
        },
        "median_fraction_closed_when_right": (
            float(np.nanmedian([x for v in by_s.values() for x in v["fraction_closed"]])) if shrink else None
        ),
        "n_right": len(shrink),
        "parameter_recovery_median_rel_error": {k: float(np.median(v)) for k, v in recov.items()},
        "pairs": pair_rows,
        "pair_outcomes": dict(Counter(p["outcome"] for p in pair_rows)),
        "confusion": _confusion(singles + nulls),
        "families": family_scores(results),
        "confusion_by_family": _family_confusion(results),
        **({"closed_loop": closed_loop_scores(results)} if any("loop" in r for r in results) else {}),
        "seconds_by_family": _seconds_by_family(results),
        "errors": [
            {"task": {k: r[k] for k in ("case", "kind", "effects", "seed")}, "error": r["error"]}
            for r in results
            if "error" in r
        ],
        "seconds_median": float(np.median([r["seconds"] for r in results])) if results else None,
        "skipped": [
            {"task": {k: r[k] for k in ("case", "kind", "effects", "seed")}, "error": r["error"]}
            for r in skipped
        ],
    }


def closed_loop_scores(results: list[dict]) -> dict:
    """The closed loop's figures (:mod:`tcamlab.loop`): every family's scores on the first
    diagnosis and on the diagnosis with the designed runs added (a case whose design proposed
    nothing keeps its first), how often the chosen protocol separates at least as well as the
    fixed default with no more runs, and one row per case."""
    rows = [r for r in results if "loop" in r]
    after = [{**r, **r["after"]} if r.get("after") else r for r in rows]
    flags = [r["loop"]["at_least_default"] for r in rows if r["loop"]["at_least_default"] is not None]
    return {
        "n": len(rows),
        "before": family_scores(rows),
        "after": family_scores(after),
        "at_least_default": {
            "k": int(sum(flags)),
            "n": len(flags),
            "rate": _rate(int(sum(flags)), len(flags)),
        },
        "within_reach": _within_reach_scores(rows, after),
        "design_promise": promise_scores(rows),
        "cases": [_loop_row(r, a) for r, a in zip(rows, after)],
    }


def promise_scores(rows: list[dict]) -> dict:
    """How well the design foresaw the precision its runs would give: over every effect
    parameter of every case, the standard error the second diagnosis reports over the one the
    design promised for the chosen protocol (``realised_sd`` / ``promised_sd`` of
    :func:`tcamlab.loop.loop_summary`): n, median and the 10th and 90th percentiles [-]."""
    ratios = [
        sd / promised
        for r in rows
        for effect, params in ((r.get("loop") or {}).get("realised_sd") or {}).items()
        for n, sd in params.items()
        if (promised := r["loop"]["promised_sd"].get(effect, {}).get(n))
    ]
    if not ratios:
        return {"n": 0, "median": None, "p10": None, "p90": None}
    p10, med, p90 = np.percentile(ratios, [10, 50, 90])
    return {"n": len(ratios), "median": float(med), "p10": float(p10), "p90": float(p90)}


def _reach(r: dict) -> bool | None:
    """Whether the menu could show the case's true effect at its true size (None: no effect, an
    off-library form, or a run made before the truth's reach was asked of every case;
    :func:`tcamlab.loop.within_reach`). Where the design did not weigh the true effect, its
    reach comes from a design that does (``truth_reach``, :func:`_truth_reach`)."""
    from tcamlab.loop import within_reach

    if not r.get("effects") or r.get("nearest"):
        return None
    eff, loop = true_effect(r), r["loop"]
    sizes = {**(loop.get("smallest_detectable") or {}), **(loop.get("truth_reach") or {})}
    return within_reach(eff, (r.get("truth_values") or {}).get(eff, {}), {"smallest_detectable": sizes})


def _within_reach_scores(rows: list[dict], after: list[dict]) -> dict:
    """{family: {strength: {k, n, rate, out_of_reach}}}: top-1 after the designed runs over the
    effect cases, leaving out those whose true effect no protocol of the menu reaches at its
    true size (the design says so instead of promising)."""
    cells: dict = defaultdict(lambda: [0, 0, 0])
    for r, a in zip(rows, after):
        fam = CASE_FAMILY.get(r["case"], r["case"])
        if fam not in ("effect-only", "realistic") or not r.get("effects"):
            continue
        cell = cells[(fam, str(float(_strength(r))))]
        if _reach(r) is False:
            cell[2] += 1
            continue
        cell[0] += int(right(a))
        cell[1] += 1
    out: dict = {}
    for (fam, st), (k, n, m) in sorted(cells.items(), key=lambda kv: (kv[0][0], float(kv[0][1]))):
        out.setdefault(fam, {})[st] = {"k": k, "n": n, "rate": _rate(k, n), "out_of_reach": m}
    return out


def _loop_row(r: dict, a: dict) -> dict:
    loop = r["loop"]
    chosen, default = loop.get("chosen") or {}, loop.get("default") or {}
    truth = ", ".join(r.get("effects") or {}) or ", ".join(r.get("offlibrary") or {}) or "-"
    return {
        "kind": r["kind"],
        "family": CASE_FAMILY.get(r["case"], r["case"]),
        "truth": truth,
        "strength": _strength(r) if r.get("effects") or r.get("offlibrary") else None,
        "before": _label(r),
        "after": _label(a),
        "right_before": right(r) if r.get("effects") else None,
        "right_after": right(a) if r.get("effects") else None,
        "protocol": chosen.get("protocol"),
        "separation": chosen.get("separation"),
        "runs": chosen.get("runs"),
        "default_separation": default.get("separation"),
        "default_runs": default.get("runs"),
        "at_least_default": loop.get("at_least_default"),
        "decisive": loop.get("decisive"),
        "reach": _reach(r),
    }


def _seconds_by_family(results: list[dict]) -> dict:
    """{family: {kind: median seconds per case}}: the per-case timings the full run is planned on."""
    cells = defaultdict(list)
    for r in results:
        cells[(CASE_FAMILY.get(r["case"], r["case"]), r["kind"])].append(r.get("seconds", 0.0))
    out: dict = {}
    for (fam, kind), v in sorted(cells.items()):
        out.setdefault(fam, {})[kind] = float(np.median(v))
    return out


def noise_ceiling(strength: float) -> float:
    """Largest held-out RMSE shrinkage any model can reach at a strength.

    An effect whose gap has RMS ``strength`` x the noise sd gives a baseline
    held-out RMSE of sqrt(1 + strength^2) noise sd; a perfect model still
    leaves the noise of the withheld run, so the shrinkage is at most
    1 - 1 / sqrt(1 + strength^2) (29 %, 68 %, 90 % at 1x, 3x, 10x).
    """
    return 1.0 - 1.0 / math.sqrt(1.0 + float(strength) ** 2)


def _shrink_cell(strength: str, cell: dict) -> dict:
    def med(v):
        v = [x for x in v if x is not None and math.isfinite(x)]
        return float(np.median(v)) if v else None

    ceiling = noise_ceiling(float(strength))
    return {
        "n": len(cell["shrinkage"]),
        "median_shrinkage": med(cell["shrinkage"]),
        "noise_ceiling": ceiling,
        "median_share_of_ceiling": med([x / ceiling for x in cell["shrinkage"]]),
        "median_share_of_attainable": med(cell["attainable"]),
        "median_fraction_closed": med(cell["fraction_closed"]),
    }


# ---------------------------------------------------------------------------
# execution
# ---------------------------------------------------------------------------


@dataclass
class BenchmarkResult:
    """Scores and raw case results of :func:`run_benchmark`."""

    scores: dict
    results: list[dict]
    paths: dict = field(default_factory=dict)
    settings: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        return to_jsonable(
            {"schema_version": 1, "settings": self.settings, "scores": self.scores, "results": self.results}
        )


def execute_tasks(tasks, scheduler=None, workers=None) -> list[dict]:
    """Run :func:`run_task` on every task: on a dask scheduler (address or cluster)
    if given, else in local processes (``workers``, default all cores)."""
    if scheduler is not None:
        from dask.distributed import Client

        client = Client(scheduler)
        try:
            futures = client.map(run_task, tasks, pure=False)
            return client.gather(futures)
        finally:
            client.close()
    workers = workers or os.cpu_count() or 1
    if workers <= 1 or len(tasks) <= 1:
        return [run_task(t) for t in tasks]
    import multiprocessing as mp

    with ProcessPoolExecutor(max_workers=workers, mp_context=mp.get_context("spawn")) as pool:
        return list(pool.map(run_task, tasks, chunksize=1))


def run_benchmark(
    out_dir,
    *,
    quick: bool = False,
    scheduler=None,
    workers=None,
    seeds: int = 10,
    kinds=None,
    effects=None,
    tasks=None,
    lies: bool = False,
    families=None,
    conditions: int = 1,
    templates=None,
    closed_loop: bool = False,
) -> BenchmarkResult:
    """Run the withheld-effect benchmark and write benchmark.json, benchmark.md and a report.

    Parameters
    ----------
    out_dir : path-like
        Output directory.
    quick : bool
        CI subset: strength 3 x 2 seeds per effect and 2 nulls per kind, no pairs
        (``seeds=1`` makes it 1 seed each).
    scheduler : str or dask Cluster, optional
        Dask scheduler address (or cluster); default: local processes.
    workers : int, optional
        Local processes (default: all cores).
    seeds : int
        Seeds per (effect, strength) in the full run.
    kinds, effects : optional
        Restrict to some kinds / effect names (tiny runs, tests).
    tasks : list of dict, optional
        Explicit task list (overrides the above).
    lies : bool
        Add the lying null cases (:func:`make_tasks`), scored apart as
        ``null_miscalibrated``.
    families : sequence of str, optional
        The families to run (:data:`FAMILIES`); default all of them.
    conditions : {1, 2}
        2: two-condition experiments (:func:`make_tasks`).
    templates : dict, optional
        {kind: experiment file}: benchmark that sample and rig instead of the bundled
        template's (:func:`make_tasks`).
    closed_loop : bool
        Close the loop on every case (:mod:`tcamlab.loop`; kinds with a protocol menu only;
        quick: one case per family and kind): design, run the design, diagnose again.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    if tasks is None:
        families = FAMILIES if families is None else tuple(families)
        tasks = make_tasks(
            quick=quick,
            seeds=seeds,
            kinds=kinds,
            effects=effects,
            lies=lies,
            families=families,
            conditions=conditions,
            templates=templates,
        )
        if closed_loop:
            tasks = loop_tasks(tasks, quick)
    t0 = time.perf_counter()
    results = execute_tasks(tasks, scheduler, workers)
    wall = time.perf_counter() - t0
    scores = score(results)
    settings = {
        "quick": bool(quick),
        "seeds": seeds,
        "n_tasks": len(tasks),
        "wall_seconds": wall,
        "generator": GENERATOR,
        "strengths": sorted({_strength(t) for t in tasks if t["case"] == "single"}),
        "executor": "dask" if scheduler is not None else f"processes ({workers or os.cpu_count()})",
        **({"lies": True} if lies else {}),
        **({"closed_loop": True} if closed_loop else {}),
        "kinds": sorted({t["kind"] for t in tasks}),
        "conditions": max((int(t.get("conditions", 1)) for t in tasks), default=1),
        **({"templates": {k: str(v) for k, v in templates.items()}} if templates else {}),
        "families": list(families)
        if families is not None
        else sorted({CASE_FAMILY[t["case"]] for t in tasks}),
        "full_run_estimate": plan_full_run(scores["seconds_by_family"], seeds=seeds, kinds=kinds),
    }
    res = BenchmarkResult(scores=scores, results=results, settings=settings)
    from tcamlab.report import render_html, render_pdf

    # Everything is rendered before anything is written: all four files or none.
    doc = report_document(res)
    payload = {
        "benchmark.json": dumps_json(res.to_dict(), indent=1, sort_keys=False).encode(),
        "benchmark.md": markdown(res).encode(),
        "benchmark.html": render_html(doc).encode(),
        "benchmark.pdf": render_pdf(doc),
    }
    files = write_all_or_nothing(out, payload)
    paths = {key: str(p) for key, p in zip(("json", "markdown", "html", "pdf"), files)}
    res.paths = paths
    return res


def plan_full_run(seconds_by_family: dict, *, seeds: int = 10, kinds=BENCHMARK_KINDS, cores: int = 2) -> dict:
    """Estimated wall time of the full run of every family, from measured per-case times.

    Each full-run task (:func:`make_tasks`, all :data:`FAMILIES`) is costed at the
    median time of its (family, kind) cell, else of its kind, else of all cells;
    the sum over ``cores`` processes is the estimate (cases are independent).

    Returns
    -------
    dict
        ``cases`` and ``seconds`` per family, ``total_seconds``, ``cores``.
    """
    flat = [v for fam in seconds_by_family.values() for v in fam.values()]
    if not flat:
        return {}
    overall = float(np.median(flat))
    by_kind = defaultdict(list)
    for fam in seconds_by_family.values():
        for k, v in fam.items():
            by_kind[k].append(v)
    out = {"cases": {}, "seconds": {}, "cores": cores}
    for t in make_tasks(seeds=seeds, kinds=kinds, families=FAMILIES):
        fam = CASE_FAMILY[t["case"]]
        cost = seconds_by_family.get(fam, {}).get(t["kind"])
        if cost is None:
            cost = float(np.median(by_kind[t["kind"]])) if by_kind.get(t["kind"]) else overall
        out["cases"][fam] = out["cases"].get(fam, 0) + 1
        out["seconds"][fam] = out["seconds"].get(fam, 0.0) + cost / cores
    out["total_seconds"] = float(sum(out["seconds"].values()))
    return out


# ---------------------------------------------------------------------------
# output
# ---------------------------------------------------------------------------


def _fmt(x, pct=False):
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "–"
    return f"{x:.0%}" if pct else f"{x:.3g}"


def _accuracy_tables(s: dict) -> list:
    def acc_rows(block):
        return [[k, str(v["n"]), _fmt(v["top1"], True), _fmt(v["top3"], True)] for k, v in block.items()]

    strengths = list(s["accuracy_by_strength"])
    by_kind = [
        [k]
        + [_fmt(v[st]["top1"], True) + f" ({v[st]['n']})" for st in strengths]
        + [_fmt(s["accuracy_by_kind"][k]["top1"], True)]
        for k, v in s["accuracy_by_kind_and_strength"].items()
    ]
    return [
        (
            "Attribution accuracy by strength (x noise RMS)",
            ["strength", "cases", "top-1", "top-3"],
            acc_rows(s["accuracy_by_strength"]),
        ),
        ("Top-1 accuracy by kind (cases)", ["kind"] + [f"{st}x" for st in strengths] + ["all"], by_kind),
        ("Accuracy by effect", ["effect", "cases", "top-1", "top-3"], acc_rows(s["accuracy_by_effect"])),
    ]


NULL_TITLE = "Null cases (no effect): false attributions"
LYING_NULL_TITLE = (
    "Null cases, miscalibrated (no effect; parameters drawn within their stated sd, "
    "noisy zeros): false attributions"
)


def _null_table(n: dict, title: str = NULL_TITLE) -> tuple:
    rows = [
        [k, str(v["n"]), str(v["false"]), ", ".join(f"{a}: {b}" for a, b in v["verdicts"].items())]
        for k, v in n["by_kind"].items()
    ]
    rows.append(["all", str(n["n"]), str(n["false_attributions"]), _fmt(n["rate"], True)])
    return (title, ["kind", "cases", "false", "verdicts"], rows)


def _shrinkage_table(by_strength: dict) -> tuple:
    keys = (
        "median_shrinkage",
        "noise_ceiling",
        "median_share_of_ceiling",
        "median_share_of_attainable",
        "median_fraction_closed",
    )
    rows = [[k, str(v["n"])] + [_fmt(v.get(c), True) for c in keys] for k, v in by_strength.items()]
    cols = [
        "strength",
        "cases",
        "median RMSE shrinkage",
        "noise ceiling 1 - 1/sqrt(1+s^2)",
        "median % of the ceiling (target >= 90 %)",
        "median share of attainable",
        "median fraction of gap closed",
    ]
    return ("Held-out shrinkage where the attribution is right, by strength", cols, rows)


def _pair_table(pairs: list[dict]) -> tuple:
    rows = [
        [
            p["kind"],
            p["pair"],
            str(p["seed"]),
            str(p["verdict"]),
            str(p["effect"]),
            ", ".join(p["aliased_with"] or []),
            p["outcome"],
        ]
        for p in pairs
    ]
    return (
        "Pairs of effects",
        ["kind", "pair", "seed", "verdict", "effect", "aliased with", "outcome"],
        rows,
    )


def _confusion_table(kind: str, conf: dict) -> tuple:
    cols = sorted({c for row in conf.values() for c in row})
    rows = [[t] + [str(row.get(c, 0)) for c in cols] for t, row in conf.items()]
    title = f"Confusion matrix, {kind} (rows: true effect; columns: diagnosis)"
    return (title, ["true \\ diagnosed"] + cols, rows)


_TOP1_TARGET = {"realistic": ">= 0.85", "off-library": ">= 0.8"}

# (key of the calibration-only scores, figure, percentage target)
_CALIBRATION_ROWS = (
    ("attributed_rate", "attributed to an effect", "<= 5%"),
    ("miscalibrated_right_rate", "miscalibrated naming a moved parameter", ">= 80%"),
    (
        "miscalibrated_right_or_partner_rate",
        "miscalibrated naming a moved parameter or its named partner (r >= 0.9)",
        "-",
    ),
)


def _proposed(fam: str, st: str) -> tuple[str, str]:
    """The proposed targets (README, "Proposed targets") of one family and strength: named
    or aliased with the verdict, and top-1 where the effect beats recalibration."""
    weak = float(st) < 3
    named = "-" if weak or fam == "off-library" else "(proposed) >= 0.9"
    if fam == "off-library":
        return named, "-" if weak else "(proposed) >= 0.8"
    return named, ("(proposed) >= 0.7" if fam == "effect-only" else "-") if weak else "(proposed) >= 0.9"


def _accuracy_rows(fam: str, st: str, a: dict) -> list[list[str]]:
    """Top-1, named-or-aliased and separable top-1 rows of one family and strength."""
    target = (">= 0.7" if float(st) < 3 else ">= 0.9") if fam == "effect-only" else _TOP1_TARGET.get(fam, "-")
    named, separable = _proposed(fam, st)
    rows = [[fam, f"top-1 at {st}x", str(a["n"]), _fmt(a["top1"]), target]]
    if a.get("named_or_aliased") is not None:
        rows.append(
            [
                fam,
                f"named, or aliased with the verdict, at {st}x",
                str(a["n"]),
                _fmt(a["named_or_aliased"]),
                named,
            ]
        )
    if a.get("separable_n"):
        rows.append(
            [
                fam,
                f"top-1 at {st}x where the effect beats recalibration on withheld runs",
                str(a["separable_n"]),
                _fmt(a["separable_top1"]),
                separable,
            ]
        )
    if fam == "off-library" and a.get("points_n"):
        k, n = a["points_right"], a["points_n"]
        rows.append(
            [
                fam,
                f"top-1 at {st}x where the withheld runs point to the nearest effect (it beats "
                "recalibration and no candidate fits them better)",
                str(n),
                f"{_fmt(k / n)} ({k} of {n})",
                "(proposed) >= 0.8",
            ]
        )
    return rows


def _family_rows(fams: dict) -> list[list[str]]:
    rows = []
    for fam in ("effect-only", "realistic", "off-library"):
        for st, a in fams.get(fam, {}).items():
            rows += _accuracy_rows(fam, st, a)
    c = fams.get("calibration-only")
    for key, figure, target in _CALIBRATION_ROWS if c else ():
        if c.get(key) is not None:
            rows.append(["calibration-only", figure, str(c["n"]), _fmt(c[key], True), target])
    for fam in NULL_FAMILIES:
        if fam in fams:
            c = fams[fam]
            rows.append([fam, "false attribution", str(c["n"]), _fmt(c["false_rate"], True), "<= 5%"])
            rows.append([fam, "none", str(c["n"]), _fmt(c["none_rate"], True), ">= 90%"])
    return rows


FAMILY_TITLE = "Families against their targets"


def _family_tables(s: dict) -> list:
    tabs = []
    if s.get("families"):
        tabs.append(
            (FAMILY_TITLE, ["family", "figure", "cases", "result", "target"], _family_rows(s["families"]))
        )
    for fam, conf in s.get("confusion_by_family", {}).items():
        for kind, c in conf.items():
            title, cols, rows = _confusion_table(kind, c)
            tabs.append((f"{fam}: {title}", cols, rows))
    return tabs


LOOP_TARGETS = {
    "top-1": ">= 0.9",
    "false attribution": "<= 5%",
    "none": ">= 90%",
    "attributed to an effect": "<= 5%",
    "miscalibrated naming a moved parameter": ">= 90%",
}
"""Targets of the closed loop after one designed experiment, by figure (off-library top-1: 0.8)."""


def _loop_target(fam: str, figure: str) -> str:
    if "point to the nearest" in figure:
        return "(proposed) >= 0.8"
    if figure.startswith("top-1 at") and "where" not in figure:
        return ">= 0.8" if fam == "off-library" else LOOP_TARGETS["top-1"]
    return LOOP_TARGETS.get(figure, "-")


def _loop_tables(c: dict) -> list:
    """The closed loop's tables: every family before and after, and one row per case."""
    before = {(r[0], r[1]): r for r in _family_rows(c["before"])}
    rows = [
        [fam, fig, n, before.get((fam, fig), ["", "", "", "-"])[3], val, _loop_target(fam, fig)]
        for fam, fig, n, val, _ in _family_rows(c["after"])
    ]
    for fam, by in (c.get("within_reach") or {}).items():
        for st, w in sorted(by.items(), key=lambda kv: float(kv[0])):
            fig = f"top-1 at {st}x, leaving out the {w['out_of_reach']} out of the menu's reach"
            rows.append([fam, fig, str(w["n"]), "-", _fmt(w["rate"]), LOOP_TARGETS["top-1"]])
    pr = c.get("design_promise") or {}
    if pr.get("n"):
        rows.append(
            [
                "all",
                "effect parameters' sd after the designed runs over the sd the design promised: median (10-90 %)",
                str(pr["n"]),
                "-",
                f"{pr['median']:.2f} ({pr['p10']:.2f}-{pr['p90']:.2f})",
                "about 1",
            ]
        )
    d = c["at_least_default"]
    rows.append(
        [
            "all",
            "designed separates at least as well as the default, no more runs",
            str(d["n"]),
            "-",
            _fmt(d["rate"], True),
            ">= 80%",
        ]
    )
    cases = [
        [
            x["kind"],
            x["family"],
            x["truth"],
            "-" if x["strength"] is None else f"{x['strength']:g}x",
            x["before"],
            x["after"],
            x["protocol"] or "-",
            _fmt(x["separation"]),
            _fmt(x["default_separation"]),
            f"{x['runs'] or '-'} / {x['default_runs'] or '-'}",
            {True: "yes", False: "no"}.get(x.get("decisive"), "-"),
            {True: "yes", False: "no"}.get(x.get("reach"), "-"),
        ]
        for x in c["cases"]
    ]
    return [
        (
            "Closed loop: the first diagnosis and the one with the designed runs added",
            ["family", "figure", "cases", "before", "after", "target"],
            rows,
        ),
        (
            "Closed loop: each case",
            [
                "kind",
                "family",
                "truth",
                "strength",
                "before",
                "after",
                "protocol",
                "J",
                "J default",
                "runs / default",
                "decisive",
                "true effect in reach",
            ],
            cases,
        ),
    ]


def _tables(res: BenchmarkResult) -> list[tuple[str, list[str], list[list[str]]]]:
    """(title, columns, rows) of every table of the benchmark's markdown and report."""
    s = res.scores
    tabs = (_loop_tables(s["closed_loop"]) if s.get("closed_loop") else []) + _family_tables(s)
    tabs += _accuracy_tables(s) + [_null_table(s["null"])]
    if s.get("null_miscalibrated"):
        tabs.append(_null_table(s["null_miscalibrated"], LYING_NULL_TITLE))
    if s.get("shrinkage_by_strength"):
        tabs.append(_shrinkage_table(s["shrinkage_by_strength"]))
    recovery = [[k, _fmt(v)] for k, v in s["parameter_recovery_median_rel_error"].items()]
    tabs.append(
        (
            "Parameter recovery, median |fitted - true| / |true| (right attributions)",
            ["effect", "median rel. error"],
            recovery,
        )
    )
    if s["pairs"]:
        tabs.append(_pair_table(s["pairs"]))
    tabs += [_confusion_table(kind, conf) for kind, conf in s["confusion"].items()]
    return tabs


def _design_lines(settings: dict) -> list[str]:
    """The experiment design in words: the templates other than the bundled ones, and two
    conditions (nothing for the bundled templates on one condition)."""
    out = [
        f"Sample and rig of the {kind} cases: **{Path(path).name}** (`--template`), under the "
        "bundled stated uncertainties scaled to its values."
        for kind, path in (settings.get("templates") or {}).items()
    ]
    out += [""] if out else []
    if int(settings.get("conditions", 1)) < 2:
        return out
    from tcamlab.rig import CONDITIONS

    return out + [
        "Design: **two conditions**. Each experiment's runs alternate between the stated "
        "condition and a second one ("
        + "; ".join(f"{k}: {v}" for k, v in CONDITIONS.items())
        + "), the experiment an aliased verdict names.",
        "",
    ]


def markdown(res: BenchmarkResult) -> str:
    """Markdown tables of a benchmark, ready to paste into a README."""
    s = res.scores
    lines = [
        "# Withheld-effect benchmark of the gap diagnosis",
        "",
        f"Generator: `{res.settings.get('generator')}`; {res.settings.get('n_tasks')} cases; "
        f"{'quick subset' if res.settings.get('quick') else 'full run'}; "
        f"wall time {res.settings.get('wall_seconds', 0):.0f} s; median "
        f"{_fmt(s['seconds_median'])} s per case.",
        "",
        *_design_lines(res.settings),
        f"Median held-out RMSE shrinkage where the attribution is right: "
        f"{_fmt(s['median_shrinkage_when_right'], True)} ({s['n_right']} cases); median "
        f"fraction of the gap above the noise floor closed: "
        f"{_fmt(s.get('median_fraction_closed_when_right'), True)}. "
        f"Null false-attribution rate: {_fmt(s['null']['rate'], True)}.",
        "",
        "Held-out RMSE includes the withheld run's noise, which no model removes: at "
        "strength s the shrinkage cannot exceed 1 - 1/sqrt(1 + s^2) (the noise ceiling "
        "in the shrinkage table).",
        "",
    ]
    plan = res.settings.get("full_run_estimate") or {}
    if plan:
        per = ", ".join(
            f"{f} {plan['cases'][f]} cases {plan['seconds'][f] / 60:.0f} min" for f in plan["cases"]
        )
        lines += [
            f"Full run of every family (seeds {res.settings.get('seeds')}), estimated from this run's "
            f"median seconds per case and kind on {plan['cores']} cores: "
            f"**{plan['total_seconds'] / 60:.0f} min** ({per}).",
            "",
        ]
    if s.get("null_miscalibrated"):
        lying = s["null_miscalibrated"]
        lines += [
            f"Null cases of a lying rig (parameters drawn within their stated sd, noisy zeros): "
            f"{lying['false_attributions']} false attributions of {lying['n']} "
            f"({_fmt(lying['rate'], True)}).",
            "",
        ]
    if s["pair_outcomes"]:
        lines += ["Pair outcomes: " + ", ".join(f"{k}: {v}" for k, v in s["pair_outcomes"].items()), ""]
    for title, cols, rows in _tables(res):
        lines += [
            f"## {title}",
            "",
            "| " + " | ".join(cols) + " |",
            "|" + "|".join("---" for _ in cols) + "|",
        ]
        lines += ["| " + " | ".join(r) + " |" for r in rows]
        lines.append("")
    if s["errors"]:
        lines += ["## Failed cases", ""] + [f"- {e['task']}: {e['error']}" for e in s["errors"]] + [""]
    if s.get("skipped"):
        lines += ["## Skipped cases (the virtual rig could not run the drawn truth; not scored)", ""]
        lines += [f"- {e['task']}: {e['error']}" for e in s["skipped"]] + [""]
    return "\n".join(lines)


def report_document(res: BenchmarkResult):
    """A tcamlab.report Document of a benchmark."""
    from tcamlab.report import Document, Section, Table

    s = res.scores
    sections = [
        Section(
            "Summary",
            paragraphs=[
                f"{res.settings.get('n_tasks')} simulated cases (generator {res.settings.get('generator')}).",
                f"Median held-out shrinkage where right: {_fmt(s['median_shrinkage_when_right'], True)} "
                f"(fraction of the gap above noise closed: "
                f"{_fmt(s.get('median_fraction_closed_when_right'), True)}); "
                f"null false-attribution rate: {_fmt(s['null']['rate'], True)}.",
                # which sample and design (markdown emphasis dropped: the report sets plain text)
                *(x.replace("**", "").replace("`", "") for x in _design_lines(res.settings) if x),
            ],
        )
    ]
    for title, cols, rows in _tables(res):
        sections.append(Section(title, tables=[Table(cols, rows, caption=title)]))
    return Document(
        "Withheld-effect benchmark",
        subtitle="tcamlab gap diagnosis",
        sections=sections,
        synthetic_banner="All data in this report is simulated.",
        metadata={
            "generator": str(res.settings.get("generator")),
            "wall time [s]": f"{res.settings.get('wall_seconds', 0):.0f}",
        },
    )
