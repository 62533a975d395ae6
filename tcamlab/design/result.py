"""Typed results of the design: each candidate protocol scored, and the choice."""

from __future__ import annotations

from dataclasses import dataclass, field

from tcamlab.jsonutil import to_jsonable

__all__ = ["CandidateProtocol", "DesignResult", "SCHEMA_VERSION"]

SCHEMA_VERSION = 1
"""Version of the :meth:`DesignResult.to_dict` layout."""


@dataclass
class CandidateProtocol:
    """One protocol of the kind's menu, scored.

    Attributes
    ----------
    name : str
        What it changes, in words.
    table : dict
        Its ``[protocol]`` table.
    runs : int
        Runs it makes.
    minutes : float
        Rig time [min].
    separation : float
        min over pairs of hypotheses of J_ij with every row independent [-] (D, an upper
        bound shown beside the criterion; :func:`tcamlab.design.score.pair_separation`);
        NaN when out of bounds.
    log_bayes_factor : float
        Expected log Bayes factor of the hardest pair, ``separation_refit`` / 2 [-].
    per_hour : float
        ``beyond_repeat`` per hour of rig time [1/h] (the repeat's own J per hour).
    pairs : dict
        "A vs B" -> D_ij [-].
    max_difference : dict
        "A vs B" -> {quantity: largest |mean_A - mean_B| over the rows [SI]}.
    feasible : bool
        Within the limits for every hypothesis.
    limit : str
        Why not, or "".
    """

    name: str
    table: dict
    runs: int
    minutes: float
    separation: float
    log_bayes_factor: float
    per_hour: float
    pairs: dict
    max_difference: dict
    feasible: bool = True
    limit: str = ""
    separation_refit: float = float("nan")
    """min over pairs of J_ij [-], the criterion: the symmetric KL divergence of the pair's
    predictive distributions with the rows' correlation kept
    (:func:`tcamlab.design.score.refit_separation`)."""
    refit: dict = field(default_factory=dict)
    """"A vs B" -> J_ij [-]."""
    beyond_repeat: float = float("nan")
    """``separation_refit`` minus the repeat's [-]: what the protocol adds beyond the protocol
    already run (0 for the repeat itself); it decides when at least ``DECISIVE``."""
    information_gain: float = float("nan")
    """A clear diagnosis: expected information gain about its explanation's parameters [nats]
    (:func:`tcamlab.design.score.information_gain`); ``per_hour`` is then this per hour."""
    failed_draws: dict = field(default_factory=dict)
    """Hypothesis -> share of its parameter draws with no solution under this protocol [-]."""
    survived: bool = False
    """No harsher than the runs already made (:mod:`tcamlab.design.survived`; the repeat
    always): the sample has been through it, so neither the model's domain at a fit nor its
    draws without a solution put it out of bounds."""
    sd_ratio: dict = field(default_factory=dict)
    """A clear diagnosis: each parameter's expected sd after the new runs over its sd now [-]."""
    at_fit: dict = field(default_factory=dict)
    """Effect hypothesis -> its Wald statistic at its fitted parameters after the runs so far and
    this protocol's, theta^T Sigma_after^-1 theta [-] (:func:`tcamlab.design.score.wald_after`):
    the evidence for the effect expected if it is as large as fitted."""
    detectable: dict = field(default_factory=dict)
    """Effect hypothesis -> {parameter: smallest |value| the runs so far and this protocol's would
    tell from zero, sqrt(``DECISIVE``) sds after [SI]}."""
    detectable_most: dict = field(default_factory=dict)
    """``detectable`` with :data:`~tcamlab.design.RUN_FACTORS`'s largest multiple of the
    protocol's runs (a protocol of the menu only): the most the design would ask of it."""
    run_factor: int = 1
    """1 for a protocol of the kind's menu; m for the same with m times its runs, scored where
    the menu's protocol falls short of deciding at the fitted sizes only by its runs."""
    decisive: bool = False
    """Expected to decide: J beyond the repeat at least ``DECISIVE`` and every effect within the
    menu's reach at least ``POWERED`` at its fit (:mod:`tcamlab.design`)."""

    def to_dict(self) -> dict:
        return to_jsonable(dict(self.__dict__))


@dataclass
class DesignResult:
    """Outcome of :func:`tcamlab.design.design`.

    Attributes
    ----------
    kind : str
    experiment : str
        The experiment's name.
    status : str
        ``ambiguous`` (hypotheses to separate), ``partial`` (no candidate explains the whole
        gap; those that explain part of it are weighed against recalibration), ``clear``,
        ``none`` or ``unexplained`` (nothing to separate).
    verdict : str
        The diagnosis's verdict.
    hypotheses : list of dict
        Each hypothesis's name and fitted parameters {value, ci95, unit} [SI].
    noise : dict
        Quantity -> noise floor sd [SI] used in the criterion.
    candidates : list of CandidateProtocol
        Best first (J per hour; out-of-bounds last).
    best : CandidateProtocol or None
        The protocol to run next (None when nothing needs separating).
    criterion : str
        The criterion, in words.
    message : str
        One sentence for the lab.
    """

    kind: str
    experiment: str
    status: str
    verdict: str
    hypotheses: list
    noise: dict
    candidates: list = field(default_factory=list)
    best: CandidateProtocol | None = None
    criterion: str = ""
    message: str = ""
    settings: dict = field(default_factory=dict)
    out_of_reach: dict = field(default_factory=dict)
    """Effect -> {parameter: {fitted, smallest, unit}}: effects no protocol of the menu would tell
    from zero at their fitted sizes (``smallest``: the size the best of them would [SI])."""

    def smallest_detectable(self) -> dict:
        """Effect -> {parameter: the smallest |value| any feasible protocol of the menu, with up
        to the most runs the design would ask of it, would tell from zero with the runs so far
        [SI]} (min over the menu's protocols of ``detectable_most``: the same whichever
        variants with more runs the design scored, which depends on the other hypotheses)."""
        out: dict = {}
        for c in self.candidates:
            for name, params in (c.detectable_most if c.feasible and c.run_factor == 1 else {}).items():
                for n, v in params.items():
                    out.setdefault(name, {})[n] = min(v, out.get(name, {}).get(n, float("inf")))
        return out

    def to_dict(self) -> dict:
        return to_jsonable(
            {
                "schema_version": SCHEMA_VERSION,
                "kind": self.kind,
                "experiment": self.experiment,
                "status": self.status,
                "verdict": self.verdict,
                "message": self.message,
                "criterion": self.criterion,
                "hypotheses": self.hypotheses,
                "noise": self.noise,
                "best": self.best.name if self.best is not None else None,
                "candidates": [c.to_dict() for c in self.candidates],
                "settings": self.settings,
                "out_of_reach": self.out_of_reach,
            }
        )
