"""Experiment design: the next protocol that tells apart what a diagnosis could not.

Steps (one module each):

1. :mod:`~tcamlab.design.hypotheses` -- the hypotheses a diagnosis left standing
   (recalibration and each aliased or stand-in effect) with their fitted parameters.
2. :mod:`~tcamlab.design.protocols` -- the kind's menu of protocol changes (static: a second
   load, heat-cool, a wider range, a longer dwell; dynamic: a second voltage, a shorter or
   longer pulse, a pulse train, logging the current or the temperature; sensing: a larger pull range, cycles, a second pull rate, a
   finer step, a longer dwell; curvature: finer levels, a larger range; selfsensing: a second
   probe voltage, a load step, a probe ripple, longer heating steps), each with its runs and
   rig time.
3. :mod:`~tcamlab.design.predict` -- every hypothesis's predicted logs under each protocol
   (the kind's outputs and the channels the protocol adds, each over its noise: the
   diagnosis's floor, else the added chain's sd),
   with their spread over draws of its parameters, and the protocol's limits (no G_t' <= 0,
   coil not closed, temperature under :data:`~tcamlab.design.predict.TEMPERATURE_LIMIT_C`).
4. :mod:`~tcamlab.design.score` -- the expected separation J of the hardest pair (the
   symmetric KL divergence of their predictive distributions, Box & Hill 1967), ranked per
   hour of rig time among the protocols expected to decide.
5. :mod:`~tcamlab.design.result` -- the typed result; :func:`protocol_toml` the file a lab
   follows and :func:`tcamlab.rig.simulate` runs.
"""

from __future__ import annotations

import numpy as np
from scipy.stats import norm

from tcamlab import progress
from tcamlab.design.hypotheses import Hypothesis, hypotheses, partial_effects, status
from tcamlab.design.predict import (
    N_DRAWS,
    anchored,
    covariance_root,
    hottest,
    limits,
    predictive,
    run_outputs,
    sensitivity,
)
from tcamlab.design.protocols import (
    Protocol,
    channel_noise,
    cost_minutes,
    menu,
    model_inputs,
    protocol_frames,
    protocol_quantities,
)
from tcamlab.design.result import CandidateProtocol, DesignResult
from tcamlab.design.score import information_gain, pair_separation, refit_separation, wald_after
from tcamlab.design.survived import no_harsher, runs_made
from tcamlab.design.toml import protocol_toml
from tcamlab.diagnosis.noise import GAP_LEVEL, gap_limit
from tcamlab.diagnosis.problem import MODEL_ERRORS
from tcamlab.kinds import get_kind
from tcamlab.text import clipped
from tcamlab.units import display

__all__ = [
    "design",
    "DesignResult",
    "CandidateProtocol",
    "Hypothesis",
    "protocol_toml",
    "DECISIVE",
    "POWERED",
    "RUN_FACTORS",
    "REACH_PROBABILITY",
]

DECISIVE = 2.0 * float(np.log(100.0))
"""Separation J [-] at which a protocol is expected to decide: an expected log Bayes factor of
ln 100 ("decisive" on Jeffreys' scale). The best protocol is the one with the most J beyond the
repeat's per hour among those whose J (:func:`~tcamlab.design.score.refit_separation`, rows
correlated) exceeds the repeat's by it (:func:`_beyond_repeat`), else the one with the most. The rows-independent D is shown beside it but not used:
on a static case with E(T) withheld, D was 17.5 and the correlated criterion 0.65 for a second
load, and the diagnosis with the designed runs added stayed aliased."""

POWERED = (float(np.sqrt(DECISIVE)) + float(norm.ppf(0.8))) ** 2
"""Wald statistic at an effect's fit [-] that a protocol should expect for the realised one to
reach :data:`DECISIVE` with a probability of 0.8 if the effect is as large as fitted
((sqrt(9.2) + 0.84)^2 = 15.0). Below it the protocol is also scored with more runs
(:data:`RUN_FACTORS`)."""

REACH_PROBABILITY = 0.5
"""Posterior probability [-] at or above which an effect the design could not tell from zero at
its fitted size still counts as within reach: the chance, under the first fit's normal
approximation, that it is at least as large as the best protocol would tell from zero. A fit
that cannot pin an effect says nothing about its size: a laser drift at 3x the noise was fitted
4e-11 m/s (95 % -3.3e-8 to 3.3e-8) on three heating runs, while a heat-cool program tells 1.6e-10
from zero; judged at the fitted size alone it was put out of reach and the design chose a
second load, after which the diagnosis stayed `miscalibrated`."""

RUN_FACTORS = (2, 3)
"""Multiples of a protocol's runs the design also scores where the protocol falls short of
:data:`POWERED` at an effect's fitted size (the same programs run again)."""

MAX_FAILED_DRAWS = 0.05
"""Largest share of a hypothesis's parameter draws for which the model may have no solution
under a protocol (G_t' <= 0 in the oven, the coil closed) beyond the share under the protocol
already run (the menu's first entry, its repeat): above it the protocol is out of bounds,
since a sample as uncertain as the fit says may not survive it. The share under the repeat is
the Gaussian's tail the runs already exclude (the sample survived them). A protocol no harsher
than the runs already made (:mod:`~tcamlab.design.survived`) is never out of bounds for its
draws or its fit's domain: an oven-lag fit at the edge of G_t' > 0 (oven runs to 150 degC,
heat-cool and two loads) had no solution for 43 % of its draws and none beside the fit on the
very runs it was fitted to, and every protocol, the repeat included, came out of bounds."""

CRITERION = (
    "J_ij = KL(i||j) + KL(j||i), the symmetric Kullback-Leibler divergence between two hypotheses' "
    "Gaussian predictive distributions of the new runs (mean over draws of the fitted parameters; "
    "covariance sigma_noise^2 I plus the draws' covariance over rows): the Box-Hill criterion, whose "
    "mean term is the T-criterion (Atkinson & Fedorov 1975) with predictive variance and whose "
    "variance term sees a nested hypothesis (a drift fitted near zero) that predicts a spread where "
    "its rival predicts none. J/2 is the expected log Bayes factor for the true one of the pair. "
    "A protocol separates as well as its hardest pair; it decides when its J exceeds the repeat's "
    "(the protocol already run, the yardstick) by 2 ln 100, and the deciding protocols are ranked "
    "by that excess per hour of rig time"
)


def noise_si(diagnosis: dict) -> dict[str, float]:
    """Noise floor sd of each quantity [SI] from a diagnosis (stored in display units)."""
    out = {}
    for q, v in diagnosis["noise_floor"]["by_quantity"].items():
        out[q] = float(v["sigma"]) / display(q)[1]
    return out


def menu_noise(kind: str, protocols, noise: dict) -> dict[str, float]:
    """``noise`` [SI] with every quantity a protocol of the menu logs beyond the kind's outputs
    (its ``channels``: :func:`~tcamlab.design.protocols.protocol_quantities`): the diagnosis's
    floor where it scored the quantity, else the added chain's sd
    (:func:`~tcamlab.design.protocols.channel_noise`)."""
    outputs = get_kind(kind).outputs
    added = [q for p in protocols for q in protocol_quantities(kind, p.table) if q not in outputs]
    return channel_noise(kind, dict.fromkeys(added), noise)


def design(experiment, diagnosis: dict, *, n_draws: int = N_DRAWS, seed: int = 0) -> DesignResult:
    """Score the kind's protocols by how well they separate the diagnosis's hypotheses.

    Parameters
    ----------
    experiment : tcamlab.config.Experiment
        The experiment diagnosed (its sample and rig are the menu's starting point).
    diagnosis : dict
        Its diagnosis in the JSON layout (:meth:`tcamlab.diagnosis.DiagnosisResult.to_dict`).
    n_draws : int
        Parameter draws per hypothesis and protocol.
    seed : int
        Seed of the draws and of the protocols' regulation errors.

    Returns
    -------
    DesignResult
    """
    kind, st = experiment.kind, status(diagnosis)
    noise = noise_si(diagnosis)
    base = DesignResult(
        kind,
        experiment.name,
        st,
        diagnosis.get("verdict", ""),
        [],
        noise,
        criterion=CRITERION,
        settings={"n_draws": n_draws, "seed": seed, "decisive": DECISIVE},
    )
    if st == "clear":
        return _precision(experiment, diagnosis, base, n_draws, seed)
    if st not in ("ambiguous", "partial"):
        base.message = _clear_message(diagnosis, st)
        return base
    hyps = hypotheses(diagnosis, kind)
    base.hypotheses = [{"name": h.name, "parameters": h.intervals} for h in hyps]
    protocols = menu(kind, experiment.sample, experiment.rig)
    noise = base.noise = menu_noise(kind, protocols, noise)
    cands, ceilings = [], _ceilings(experiment, protocols[0], hyps, seed)
    made = runs_made(experiment)
    with progress.task("designing: scoring protocols", total=len(protocols)) as step:
        for k, p in enumerate(protocols):
            cands.extend(_score(experiment, p, hyps, noise, n_draws, seed, ceilings, (made, k == 0)))
            step()
    _mark_risky(cands)
    base.out_of_reach = _decide(cands, hyps)
    cands.sort(key=lambda c: (not c.feasible, -np.nan_to_num(c.per_hour, nan=-1.0)))
    base.candidates, base.best = cands, _best(cands)
    base.message = _partial_words(diagnosis) + _message(base, hyps)
    return base


def _partial_words(diagnosis: dict) -> str:
    """What an ``unexplained`` verdict's partial explanations close (empty otherwise)."""
    names = partial_effects(diagnosis)
    if not names:
        return ""
    by = {c["effect"]: c for c in diagnosis.get("ranking") or []}
    limit = (diagnosis.get("gap") or {}).get("limit", float("nan"))
    parts = [
        f"{n} closes {by[n]['fraction_closed']:.0%} and leaves {by[n]['heldout_rmse_after_noise']:.2f} x the noise"
        for n in names
    ]
    return (
        f"no candidate explains the whole gap ({'; '.join(parts)} on withheld runs, no-gap limit "
        f"{limit:.2f}): the protocol below tests {'it' if len(names) == 1 else 'them'} against "
        "recalibration, so that the next diagnosis can keep or rule out each part (an effect "
        "outside the library may act beside or instead of it); "
    )


def _decide(cands: list[CandidateProtocol], hyps) -> dict:
    """Mark the protocols expected to decide; return the effects out of every protocol's reach
    (the protocols' J then counts only the pairs within reach, :func:`_separation_within_reach`,
    and what each adds beyond the repeat, :func:`_beyond_repeat`).

    An effect is out of reach when no protocol of the menu, with up to the largest of
    :data:`RUN_FACTORS` times its runs, would tell it from zero at its fitted size (``at_fit``
    below :data:`DECISIVE` under every feasible one) and it is unlikely to be larger
    (:func:`reach_probability` below :data:`REACH_PROBABILITY`): then, if it is the truth,
    nothing here will show it, and the design says so instead of counting on J, whose spread
    over a wide posterior promises otherwise. A protocol decides when its J beyond the repeat
    is at least :data:`DECISIVE` and it expects every effect within reach at :data:`POWERED`
    at its plausible size (:func:`_sized_statistic`); with every effect out of reach, none
    decides.
    """
    ok = [c for c in cands if c.feasible]
    effects = [h for h in hyps if h.effect_values.size]
    at_fit = {h.name: max((_statistic(c, h.name) for c in ok), default=0.0) for h in effects}
    out = {}
    for h in effects:
        chance = max((reach_probability(h, c) for c in ok), default=0.0)
        if at_fit[h.name] >= DECISIVE or chance >= REACH_PROBABILITY:
            continue
        best = max(ok, key=lambda c: _statistic(c, h.name), default=None)
        need = best.detectable.get(h.name, {}) if best is not None else {}
        out[h.name] = {
            n: {
                "fitted": float(h.intervals[n]["value"]),
                "smallest": v,
                "unit": h.intervals[n].get("unit"),
                "chance": chance,
            }
            for n, v in need.items()
        }
    within = [h for h in effects if h.name not in out]
    _separation_within_reach(cands, set(out))
    _beyond_repeat(cands)
    for c in cands:
        c.decisive = bool(
            c.feasible
            and within
            and c.beyond_repeat >= DECISIVE
            and all(_sized_statistic(c, h) >= POWERED for h in within)
        )
    return out


def _statistic(c: CandidateProtocol, name: str) -> float:
    """Effect ``name``'s Wald statistic at its fit under ``c`` (0 where it has none)."""
    return float(np.nan_to_num(c.at_fit.get(name, 0.0), nan=0.0))


def _sized_statistic(c: CandidateProtocol, h: Hypothesis) -> float:
    """Effect ``h``'s Wald statistic under ``c`` at its plausible size: its fitted size, or one
    standard error of the first fit in a parameter where that is larger (then sd^2 over the sd
    after ``c``'s runs, ``c.detectable`` being sqrt(DECISIVE) of the latter). Where the first
    fit cannot tell the effect from zero its fitted size is chance, and power there would ask
    the impossible: the drift above, fitted at 4e-11 m/s, made every protocol fall short."""
    w = _statistic(c, h.name)
    for _, _, sd, d in _effect_sizes(c, h):
        w = max(w, DECISIVE * (sd / d) ** 2)
    return w


def reach_probability(h: Hypothesis, c: CandidateProtocol) -> float:
    """Probability [-] that effect hypothesis ``h`` is at least as large as protocol ``c`` would
    tell from zero, in any one of its parameters: P(|theta| >= d) with theta normal about the
    fitted value with the fit's standard error and d the size ``c`` tells from zero
    (``c.detectable``; 0 where ``c`` has none)."""
    return max(
        (float(norm.sf((d - v) / sd) + norm.cdf((-d - v) / sd)) for _, v, sd, d in _effect_sizes(c, h)),
        default=0.0,
    )


def _effect_sizes(c: CandidateProtocol, h: Hypothesis):
    """``(name, fitted value, standard error, size c tells from zero)`` of each of effect
    ``h``'s parameters for which all three are finite and the last two positive."""
    need = c.detectable.get(h.name) or {}
    for name, v, sd in zip(h.effect_names, h.effect_values, h.effect_sd):
        d = need.get(name)
        if d is not None and np.isfinite([d, v, sd]).all() and d > 0 and sd > 0:
            yield name, float(v), float(sd), float(d)


def _separation_within_reach(cands: list[CandidateProtocol], out_of_reach: set) -> None:
    """Each protocol's J and D over the pairs of hypotheses within reach (both left as they are
    when no pair is).

    An effect out of reach predicts, under every protocol, what recalibration predicts to
    within the noise at its fitted size, so its pair with recalibration has a J near zero
    everywhere: as the hardest pair it would hold every protocol short of deciding between the
    hypotheses that can be told apart. Static E(T) at 3x (synthetic, parameters one stated sd
    off): with G(T) fitted at 5e3 Pa/K (out of reach) in the pairs, "second load 2x" scored J
    1.6 and nothing decided; recalibration against E(T) alone scored 163. Its pairs stay in
    ``refit`` and ``pairs`` for the reader."""
    if not out_of_reach:
        return

    def kept(scores: dict) -> dict:
        return {k: v for k, v in scores.items() if not out_of_reach.intersection(k.split(" vs "))}

    for c in cands:
        refit, pairs = kept(c.refit), kept(c.pairs)
        if refit and pairs:
            c.separation_refit, c.separation = float(min(refit.values())), float(min(pairs.values()))
            c.log_bayes_factor = c.separation_refit / 2.0


def _predicted(
    kind, sample, rig, frames, h, n_draws: int, seed: int, quantities=None, ceiling=None, survived=False
):
    """``(prediction, None)`` of hypothesis ``h`` under a protocol's ``frames`` (of
    ``quantities``, default the kind's outputs), or ``(None or prediction, why)`` where it has
    no solution there or breaks a limit (``ceiling``: :func:`_ceilings`; none where the
    protocol is one the sample has ``survived``)."""
    pred, point = predictive(kind, sample, rig, frames, h, n_draws, seed, quantities)
    if pred is None or survived:
        return pred, (point if pred is None else None)
    why = limits(kind, h.at(h.u(), h.effect_values, sample, rig, kind)[0], frames, point, ceiling)
    return pred, (f"{h.name}: {why}" if why else None)


def _ceilings(experiment, proto: Protocol, hyps, seed: int) -> dict[str, float]:
    """The hottest temperature [degC] each hypothesis's fit predicts under the protocol already
    run (the menu's first entry, its repeat). The sample survived those runs, so a fit that
    heats it past the limit there rules out only what would heat it further: a dynamic R(T) fit
    (synthetic, stated G_t' = 0, convective loss at 3x) put the pulse run at 182 degC, and
    every protocol, the repeat included, was out of bounds. None where the fit has no
    solution there (its protocols are then judged by the limit alone)."""
    kind, sample, rig = experiment.kind, experiment.sample, experiment.rig
    frames = protocol_frames(kind, rig, proto.table, seed)
    inputs, why = _inputs(kind, sample, rig, frames, hyps[0])
    out = {}
    for h in [] if why else hyps:
        s, r, mods = h.at(h.u(), h.effect_values, sample, rig, kind)
        try:
            out[h.name] = hottest(inputs, run_outputs(kind, s, r, mods, inputs))
        except (*MODEL_ERRORS, ValueError):
            continue
    return out


def _mark_risky(cands: list[CandidateProtocol]) -> None:
    """Out of bounds: a protocol under which more of a hypothesis's draws have no solution than
    under the repeat (the first candidate) by :data:`MAX_FAILED_DRAWS`; never one the sample has
    been through (``survived``)."""
    base = cands[0].failed_draws if cands else {}
    for c in cands[1:]:
        for name, f in c.failed_draws.items():
            # draws the runs already made exclude: the sample has been through this protocol
            if c.feasible and not c.survived and f > base.get(name, 0.0) + MAX_FAILED_DRAWS:
                c.feasible = False
                c.limit = (
                    f"{name}: the model has no solution for {f:.0%} of its parameter draws "
                    f"({base.get(name, 0.0):.0%} under the repeat): the sample may not survive it"
                )


def _been_through(kind, sample, rig, frames, hyps, n_draws: int, seed: int, quantities):
    """``(hyps, None)`` for a protocol no harsher than the runs already made, each centred where
    the model has a solution under it and beside it (its fit, else its nearest draw that has:
    :func:`~tcamlab.design.predict.anchored`), or ``(hyps, why)`` where one has none at any
    draw (then not scored: the model's domain ends short of what the sample went through)."""
    out = []
    for h in hyps:
        a = anchored(kind, sample, rig, frames, h, n_draws, seed, quantities)
        if a is None:
            return hyps, (
                f"{h.name}: no solution at its fit or any of its draws, though the runs already "
                "made were as harsh (the model's domain, not the sample's)"
            )
        out.append(a)
    return out, None


def _inputs(kind, sample, rig, frames, h):
    """``(inputs, None)``: each run's model inputs under its program at ``h``'s fit, shared by
    every hypothesis (the resistances a sensor reads; a static or dynamic program is its own
    input), or ``(frames, why)`` where the fitted sensor gives no reading there."""
    s, r, _ = h.at(h.u(), h.effect_values, sample, rig, kind)
    try:
        return model_inputs(kind, s, r, frames), None
    except MODEL_ERRORS as exc:
        return frames, f"{h.name}: no reading under this program ({clipped(str(exc).split(';')[0])})"


def _clear_message(diagnosis: dict, st: str) -> str:
    if st == "none":
        return _none_message(diagnosis.get("gap") or {})
    if st == "unexplained":
        return "no candidate explains the gap, so there are no hypotheses to separate: an effect outside the library is needed, not another protocol"
    left = _gap_left(diagnosis)
    if left is not None:
        return (
            f"the diagnosis names one explanation ({diagnosis.get('verdict')}: {_explanation(diagnosis)}), "
            f"but it leaves {left[0]:.2f} x the noise floor on withheld data, above the no-gap limit "
            f"{left[1]:.2f}: no protocol from the menu separates a form the library does not have; "
            "an effect outside the library may act"
        )
    return f"the diagnosis is clear ({diagnosis.get('verdict')}: {_explanation(diagnosis)}); no further experiment is needed to tell hypotheses apart"


def _none_message(gap: dict) -> str:
    """No gap: nothing to separate, and how small a gap these runs could have shown. One run
    of the static oven (26 points, a noise estimate of 12 degrees of freedom) passes a laser
    drift of 3x the noise at 1.92 x the floor under a limit of 1.92: "fits within the noise"
    alone would read as a pass the data cannot give."""
    words = "the thesis model fits within the noise: there are no hypotheses to separate"
    keys = ("rmse_over_noise", "limit", "n_points", "noise_dof")
    if not all(isinstance(gap.get(k), (int, float)) and np.isfinite(gap[k]) for k in keys):
        return words
    n, nu, level = int(gap["n_points"]), float(gap["noise_dof"]), float(gap.get("level", GAP_LEVEL))
    # the stored limit pools quantities; the one-quantity ratio scales it to twice the runs
    after = gap["limit"] * gap_limit(2 * n, 2 * nu, level) / gap_limit(n, nu, level)
    return (
        f"{words} (baseline {gap['rmse_over_noise']:.2f} x the noise floor, under the no-gap limit "
        f"{gap['limit']:.2f} of these {n} points: a smaller gap would not show; as many runs again "
        f"of the same protocol would lower the limit to about {after:.2f})"
    )


def _gap_left(diagnosis: dict) -> tuple[float, float] | None:
    """(held-out RMSE, no-gap limit) [noise floors] of the explanation a diagnosis names when
    it leaves more than the limit (:func:`tcamlab.diagnosis.verdict.gap_left`), else None."""
    named = diagnosis.get("combination") or next(
        (
            c
            for c in diagnosis.get("ranking") or []
            if c.get("effect") == (diagnosis.get("effect") or "recalibration")
        ),
        None,
    )
    limit = (diagnosis.get("gap") or {}).get("limit")
    after = (named or {}).get("heldout_rmse_after_noise")
    if after is None or limit is None or not after > limit:
        return None
    return float(after), float(limit)


def _explanation(diagnosis: dict) -> str:
    """What a clear diagnosis names: its effect, else the recalibrated parameters that moved
    (a ``miscalibrated`` verdict has no effect), else its verdict."""
    if diagnosis.get("effect"):
        return str(diagnosis["effect"])
    moved = (diagnosis.get("recalibration") or {}).get("named") or []
    if moved:
        return ", ".join(moved) + " moved"
    return str(diagnosis.get("verdict"))


def _beyond_repeat(cands: list[CandidateProtocol]) -> None:
    """Each protocol's J beyond the repeat's (the first candidate) and that per hour.

    The repeat is the yardstick: the diagnosis found the hypotheses alike on the protocol
    already run, so what J promises there is the Gaussian approximation's error (draws of a
    model that bends near the edge of its domain spread where the fit is pinned; a curvature
    sensor's repeat scored J 52 with both hypotheses within the noise on withheld runs) or
    evidence the runs so far could already have given. Only what a protocol adds beyond it
    counts towards deciding."""
    yard = cands[0].separation_refit if cands and cands[0].feasible else 0.0
    yard = float(yard) if np.isfinite(yard) else 0.0
    for k, c in enumerate(cands):
        c.beyond_repeat = 0.0 if k == 0 else c.separation_refit - yard
        c.per_hour = (
            max(c.beyond_repeat, 0.0) / (c.minutes / 60.0) if k else c.separation_refit / (c.minutes / 60.0)
        )


def _best(cands: list[CandidateProtocol]) -> CandidateProtocol | None:
    ok = [c for c in cands if c.feasible and np.isfinite(c.separation) and c.separation > 0]
    decisive = [c for c in ok if c.decisive]
    if decisive:
        return max(decisive, key=lambda c: c.per_hour)
    # none decides: the menu's own protocols only (more runs are offered to decide, not to
    # spend on a protocol that would not)
    base = [c for c in ok if c.run_factor == 1]
    return max(base, key=lambda c: (round(c.beyond_repeat, 1), -c.runs, c.separation)) if base else None


def _message(res: DesignResult, hyps) -> str:
    names = " vs ".join(h.name for h in hyps if h.name not in res.out_of_reach)
    b = res.best
    if b is None:
        return f"no protocol of the {res.kind} menu separates {names} within the limits"
    verdict = "is expected to decide" if b.decisive else "separates best, but not decisively,"
    return (
        f"{b.name} {verdict} between {names}: separation J {b.separation_refit:.3g}, "
        f"{b.beyond_repeat:.3g} beyond a repeat of the protocol run (decisive from {DECISIVE:.1f}: an "
        f"expected Bayes factor of 100), {b.runs} runs, {b.minutes:.0f} min" + _out_of_reach(res)
    )


def _out_of_reach(res: DesignResult) -> str:
    """The effects no protocol of the menu would tell from zero at their fitted sizes, with
    the smallest size the best one would and the chance that the effect is that large (empty
    when none)."""
    parts = []
    for name, params in res.out_of_reach.items():
        sizes = [
            f"{n} fitted {p['fitted']:.3g}, the best protocol needs {p['smallest']:.3g} {p.get('unit') or ''}".rstrip()
            for n, p in params.items()
        ]
        chance = max((p.get("chance", 0.0) for p in params.values()), default=None)
        if chance is not None:
            sizes.append(f"a {chance:.0%} chance that it is that large")
        parts.append(f"{name} ({'; '.join(sizes) or 'no solution near its fit'})")
    if not parts:
        return ""
    return "; out of reach of every protocol here at its fitted size: " + ", ".join(parts)


def _score(
    experiment, proto: Protocol, hyps, noise, n_draws: int, seed: int, ceilings=None, made=((), False)
) -> list[CandidateProtocol]:
    """One protocol scored (predictions of every hypothesis, limits, J and D of every pair, each
    effect's statistic at its fit), then the same with :data:`RUN_FACTORS` times its runs where
    it falls short of :data:`POWERED` at the fit. The quantities scored are the kind's outputs
    and those the protocol's ``channels`` add (:func:`~tcamlab.design.protocols.protocol_quantities`),
    each over its sd in ``noise``; a channel adds no runs and no rig time. ``made``: (the runs
    already made [SI], whether ``proto`` is the repeat), for :func:`_been_through`."""
    kind, sample, rig = experiment.kind, experiment.sample, experiment.rig
    frames = protocol_frames(kind, rig, proto.table, seed)
    minutes = cost_minutes(frames, kind)
    quantities = protocol_quantities(kind, proto.table)
    nan = float("nan")
    out = CandidateProtocol(proto.name, proto.table, len(frames), minutes, nan, nan, nan, {}, {})
    out.survived = made[1] or no_harsher(frames, made[0], rig)
    frames, why = _inputs(kind, sample, rig, frames, hyps[0])
    if not why and out.survived:
        hyps, why = _been_through(kind, sample, rig, frames, hyps, n_draws, seed, quantities)
    if why:
        out.feasible, out.limit = False, why
        return [out]
    preds = []
    for h in hyps:
        ceiling = (ceilings or {}).get(h.name)
        pred, why = _predicted(kind, sample, rig, frames, h, n_draws, seed, quantities, ceiling, out.survived)
        if why:
            out.feasible, out.limit = False, why
            return [out]
        out.failed_draws[h.name] = pred.failed
        preds.append(pred)
    pairs = [(i, j) for i in range(len(hyps)) for j in range(i + 1, len(hyps))]
    scale = {(i, j): max(1.0, hyps[i].misfit, hyps[j].misfit) for i, j in pairs}
    D = {
        (i, j): sum(
            pair_separation(
                preds[i].mean[q],
                preds[i].var[q],
                preds[j].mean[q],
                preds[j].var[q],
                (noise[q] * scale[i, j]) ** 2,
            )
            for q in quantities
        )
        for i, j in pairs
    }
    out.max_difference = {
        f"{hyps[i].name} vs {hyps[j].name}": {
            q: float(np.max(np.abs(preds[i].mean[q] - preds[j].mean[q]))) for q in preds[i].mean
        }
        for i, j in pairs
    }
    stacked = [_normalised_draws(p, noise, quantities) for p in preds]
    sens = _sensitivities(kind, sample, rig, frames, hyps, noise, quantities, out.survived)
    parts = (hyps, stacked, sens, D, scale)
    _fill(out, parts, 1)
    return [out] + _more_runs(out, parts)


def _more_runs(out: CandidateProtocol, parts) -> list[CandidateProtocol]:
    """The protocol with :data:`RUN_FACTORS` times its runs, up to the first that gets every
    effect to :data:`POWERED` at its fit; none when its own runs do, or when no effect's
    statistic is within the largest factor of :data:`DECISIVE`. (The statistic grows more
    slowly than the runs where the new runs cannot tell the effect from a recalibrated
    parameter: repeating them pins what they see, not what they miss.)"""
    # an effect whose statistic more runs could lift to DECISIVE, were it to grow with them
    short = [w for w in out.at_fit.values() if np.isfinite(w) and DECISIVE / max(RUN_FACTORS) <= w < POWERED]
    variants = []
    for m in RUN_FACTORS if short else ():
        nan = float("nan")
        v = CandidateProtocol(
            f"{out.name}, {m}x the runs", {**out.table, "runs": m * out.runs}, m * out.runs,
            m * out.minutes, nan, nan, nan, {}, dict(out.max_difference), failed_draws=dict(out.failed_draws),
            run_factor=m, survived=out.survived,
        )  # fmt: skip
        _fill(v, parts, m)
        variants.append(v)
        if all(w >= POWERED for w in v.at_fit.values() if np.isfinite(w) and w > 0):
            break
    return variants


def _fill(out: CandidateProtocol, parts, m: int) -> None:
    """J, D, the effects' statistics at their fits and the sizes they would detect, for ``m``
    copies of the protocol's runs (the same programs again: D and the new runs' information
    scale by ``m``; J is computed on the draws repeated ``m`` times)."""
    hyps, stacked, sens, D, scale = parts
    label = {(i, j): f"{hyps[i].name} vs {hyps[j].name}" for i, j in D}
    out.pairs = {label[k]: m * d for k, d in D.items()}
    out.refit = {
        label[i, j]: refit_separation(np.tile(stacked[i], m), np.tile(stacked[j], m), scale[i, j])
        for i, j in D
    }
    out.separation_refit = float(min(out.refit.values())) if D else float("inf")
    out.separation = float(min(out.pairs.values())) if D else float("inf")
    out.log_bayes_factor = out.separation_refit / 2.0
    out.per_hour = out.separation_refit / (out.minutes / 60.0)
    for h in hyps:
        if h.name not in sens:
            continue
        if sens[h.name] is None:
            out.at_fit[h.name] = float("nan")
            continue
        root, names = covariance_root(h)[h.u().size :, :], h.effect_names
        out.at_fit[h.name], out.detectable[h.name] = _told_from_zero(sens[h.name], root, h, names, m)
        if m == 1:  # the most runs the design would ask of this protocol
            out.detectable_most[h.name] = _told_from_zero(sens[h.name], root, h, names, max(RUN_FACTORS))[1]


def _told_from_zero(B, root, h, names, m: int) -> tuple[float, dict]:
    """(Wald statistic of ``h``'s effect at its fit, {parameter: the size told from zero,
    sqrt(``DECISIVE``) sds after [SI]}) with ``m`` copies of a protocol's runs (sensitivity ``B``)."""
    w, sd = wald_after(np.sqrt(m) * B, root, h.effect_values)
    return w, {n: float(np.sqrt(DECISIVE) * v) for n, v in zip(names, sd)}


def _sensitivities(kind, sample, rig, frames, hyps, noise: dict, quantities=None, one_sided=False) -> dict:
    """Effect hypothesis -> its predictions' sensitivity to one posterior sd of each
    standardised parameter, rows of each of ``quantities`` (default the kind's outputs) over
    its noise (None where the model has no solution near the fit;
    :func:`~tcamlab.design.predict.sensitivity`, ``one_sided`` as there)."""
    quantities = get_kind(kind).outputs if quantities is None else quantities
    out = {}
    for h in hyps:
        if not h.effect_values.size:
            continue
        try:
            sens = sensitivity(kind, sample, rig, frames, h, quantities, one_sided)
        except (*MODEL_ERRORS, ValueError):
            out[h.name] = None
            continue
        scale = max(1.0, h.misfit)  # the pair's noise in J is scaled the same way
        out[h.name] = np.vstack([sens[q] / (noise[q] * scale) for q in quantities])
    return out


def _normalised_draws(pred, noise: dict, outputs) -> np.ndarray:
    """Every quantity's draws over its noise floor, side by side (draws, rows of all quantities):
    the quantities share each draw's parameters, so they are one vector, not independent."""
    return np.hstack([pred.draws[q] / noise[q] for q in outputs])


def _precision(experiment, diagnosis: dict, base: DesignResult, n_draws: int, seed: int) -> DesignResult:
    """A clear diagnosis: nothing to separate; the protocols ranked by what they would add to the
    precision of its explanation's parameters (expected information gain per hour)."""
    kind = experiment.kind
    h = hypotheses(diagnosis, kind)[0]
    base.hypotheses = [{"name": h.name, "parameters": h.intervals}]
    protos = menu(kind, experiment.sample, experiment.rig)
    base.noise = menu_noise(kind, protos, base.noise)
    ceiling = _ceilings(experiment, protos[0], [h], seed).get(h.name)
    made = runs_made(experiment)
    cands = [
        _score_precision(experiment, p, h, base.noise, n_draws, seed, ceiling, (made, k == 0))
        for k, p in enumerate(protos)
    ]
    _mark_risky(cands)
    cands.sort(key=lambda c: (not c.feasible, -np.nan_to_num(c.per_hour, nan=-1.0)))
    base.candidates = cands
    ok = [c for c in cands if c.feasible and c.information_gain > 0]
    base.best = max(ok, key=lambda c: c.per_hour) if ok else None
    base.message = _clear_message(diagnosis, "clear")
    if base.best is not None:
        b = base.best
        base.message += (
            f"; for more precise parameters, {b.name} adds {b.information_gain:.1f} nats "
            f"({b.runs} runs, {b.minutes:.0f} min)"
        )
    return base


def _score_precision(
    experiment, proto: Protocol, h, noise, n_draws: int, seed: int, ceiling=None, made=((), False)
) -> CandidateProtocol:
    """One protocol scored by the expected information gain about ``h``'s parameters and each
    parameter's expected sd after / before (on the kind's outputs and the protocol's channels,
    as :func:`_score`; ``made`` as there)."""
    kind, sample, rig = experiment.kind, experiment.sample, experiment.rig
    frames = protocol_frames(kind, rig, proto.table, seed)
    minutes = cost_minutes(frames, kind)
    quantities = protocol_quantities(kind, proto.table)
    nan = float("nan")
    out = CandidateProtocol(proto.name, proto.table, len(frames), minutes, nan, nan, nan, {}, {})
    out.survived = made[1] or no_harsher(frames, made[0], rig)
    frames, why = _inputs(kind, sample, rig, frames, h)
    if not why and out.survived:
        (h,), why = _been_through(kind, sample, rig, frames, [h], n_draws, seed, quantities)
    if why:
        out.feasible, out.limit = False, why
        return out
    pred, why = _predicted(kind, sample, rig, frames, h, n_draws, seed, quantities, ceiling, out.survived)
    if why:
        out.feasible, out.limit = False, why
        return out
    out.failed_draws[h.name] = pred.failed
    try:
        sens = sensitivity(kind, sample, rig, frames, h, quantities, out.survived)
    except (*MODEL_ERRORS, ValueError) as exc:
        out.feasible, out.limit = False, f"{h.name}: no solution near the fit ({clipped(str(exc))})"
        return out
    gain, post = information_gain(np.vstack([sens[q] / noise[q] for q in quantities]))
    root = covariance_root(h)
    after, before = np.diag(root @ post @ root.T), np.diag(root @ root.T)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.sqrt(after / before)
    out.sd_ratio = {n: float(r) for n, r in zip(h.intervals, ratio)}
    out.information_gain = gain
    out.per_hour = gain / (minutes / 60.0)
    return out
