"""Typed results of a calibration and their JSON form (schema in README, "Calibration")."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace

import numpy as np

__all__ = [
    "SCHEMA_VERSION",
    "ParameterEstimate",
    "ZeroEstimate",
    "FitQuality",
    "RunCurves",
    "CalibrationResult",
]

SCHEMA_VERSION = 1
"""Version of ``calibration.json``."""


@dataclass(frozen=True)
class ParameterEstimate:
    """One calibrated parameter (values in SI, ``unit``).

    Attributes
    ----------
    name : str
        ``field`` or ``EXPERIMENT.field``.
    field, where, symbol, unit : str
        SI field, ``"sample"`` or ``"rig"``, thesis symbol, SI unit.
    key : str
        Experiment-file key (lab units).
    stated : float
        Prior centre [unit]: the file's value, or identified from the logs when unstated.
    stated_in_file : bool
        Whether the file (or its preset) states the value.
    stated_sd : float or None
        The file's stated sd [unit], None when unstated.
    prior_sd : float
        Prior sd used [unit] (stated, or the kind's documented default).
    value : float
        MAP value [unit].
    posterior_sd : float
        Laplace sd [unit] (delta method from log space for positive parameters).
    posterior_sd_rel, prior_sd_rel : float
        Posterior and prior sd in log space (relative) [-].
    laplace_95, profile_95 : tuple of float
        95 % intervals [unit]: Jacobian (Laplace) and profile likelihood.
    profile_open : tuple of bool
        Whether each profile bound is the search box (the likelihood never rose by 3.84).
    shift_in_stated_sds : float or None
        (value - stated) / stated_sd [-]; None without a stated sd.
    pinned : bool
        ``identification == "pinned"``.
    identification : str
        ``"pinned"`` (relative posterior sd at most 10 % and at most 0.158 of the prior's),
        ``"constrained"`` (the logs at least halve the prior sd) or ``"prior"`` (rests on its
        prior); see :func:`tcamlab.calibration.identify.tier`.
    pinned_by : str
        The experiment that would pin it.
    profile_points : tuple of (float, float)
        The profile likelihood as evaluated by the interval search, sorted by value:
        ``(value [unit], signed root z)`` with ``z = sign(value - MAP) * sqrt(chi2_profile
        - chi2_min)`` [-]; the MAP point ``(value, 0)`` included. ``|z| = 1.96`` is the
        95 % bound.
    positive : bool
        Fitted as its logarithm: a log-normal prior of relative sd ``prior_sd_rel``.
    """

    name: str
    field: str
    where: str
    symbol: str
    unit: str
    key: str
    stated: float
    stated_in_file: bool
    stated_sd: float | None
    prior_sd: float
    value: float
    posterior_sd: float
    posterior_sd_rel: float
    prior_sd_rel: float
    laplace_95: tuple[float, float]
    profile_95: tuple[float, float]
    profile_open: tuple[bool, bool]
    shift_in_stated_sds: float | None
    pinned: bool
    identification: str
    pinned_by: str
    profile_points: tuple[tuple[float, float], ...] = ()
    positive: bool = True


@dataclass(frozen=True)
class ZeroEstimate:
    """One run's nuisance zero of one quantity.

    Attributes
    ----------
    experiment, run, quantity : str
        Experiment name, run file name, internal quantity.
    value, sd : float
        The zero (measured - predicted offset) and its sd [SI of the quantity].
    interval_95 : tuple of float
        value +- 1.96 sd [SI].
    """

    experiment: str
    run: str
    quantity: str
    value: float
    sd: float
    interval_95: tuple[float, float]


@dataclass(frozen=True)
class FitQuality:
    """Residuals of one quantity of one experiment before and after calibration.

    Attributes
    ----------
    experiment, quantity : str
        Experiment name and internal quantity.
    sigma : float
        Noise floor from second differences [SI].
    rmse_over_sigma_stated : float
        RMSE / sigma at the stated values with the logged zeros [-].
    rmse_over_sigma_calibrated : float
        RMSE / sigma at the calibrated values with the fitted zeros [-].
    n : int
        Points.
    """

    experiment: str
    quantity: str
    sigma: float
    rmse_over_sigma_stated: float
    rmse_over_sigma_calibrated: float
    n: int


@dataclass(frozen=True)
class RunCurves:
    """One run's measured and predicted curves at the stated and calibrated values, for the
    report's overlays and residual plots (not in ``calibration.json``).

    Attributes
    ----------
    experiment, run, kind : str
        Experiment name, run file name, rig kind.
    x : str
        Internal name of the physical input the residuals are drawn against
        (:attr:`tcamlab.kinds.Kind.x_column`: time, temperature, cable...).
    inputs : dict of str to ndarray
        ``x`` (and ``time`` when logged) per row [SI].
    measured : dict of str to ndarray
        Each fitted quantity as logged [SI].
    stated : dict of str to ndarray
        Predicted at the stated values, with the logged zero [SI].
    calibrated : dict of str to ndarray
        Predicted at the calibrated values plus the run's fitted zero [SI].
    zero : dict of str to float
        The fitted nuisance zero of each zero-referenced quantity [SI].
    """

    experiment: str
    run: str
    kind: str
    x: str
    inputs: dict[str, np.ndarray]
    measured: dict[str, np.ndarray]
    stated: dict[str, np.ndarray]
    calibrated: dict[str, np.ndarray]
    zero: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class CalibrationResult:
    """Outcome of :func:`tcamlab.calibration.calibrate`.

    Attributes
    ----------
    experiments : list of str
        Experiment files, as given.
    kinds : list of str
        Their kinds.
    parameters : list of ParameterEstimate
    zeros : list of ZeroEstimate
    fit : list of FitQuality
    correlation : dict
        ``{"names": [...], "matrix": [[...]]}``: posterior correlation in fitted (log) coordinates [-].
    directions : list of dict
        Eigen-combinations: ``exponents``, ``ratio`` (posterior / prior sd), ``relative_sd``, ``pinned``.
    identifiability : list of str
        The identifiability report in words.
    chi2 : float
        Penalised chi-square at the MAP point [-].
    n_points : int
        Data points fitted.
    notes : list of str
        Remarks.
    inputs : list of dict
        Every input file read: ``experiment``, ``role`` ("experiment", "run", or "joined" for a run's second instrument file),
        ``path`` (as given or as listed in the experiment file) and ``sha256``.
    curves : list of RunCurves
        Per-run curves for the report; arrays, so left out of :meth:`to_dict`.
    estimator : list of EstimatorFit
        The second stage of a self-sensing experiment: R0, TCR, R_lead and k_s refitted
        through the EKF (:mod:`tcamlab.calibration.estimator`); empty for other kinds.
    """

    experiments: list[str]
    kinds: list[str]
    parameters: list[ParameterEstimate]
    zeros: list[ZeroEstimate]
    fit: list[FitQuality]
    correlation: dict
    directions: list[dict]
    identifiability: list[str]
    chi2: float
    n_points: int
    notes: list[str] = field(default_factory=list)
    inputs: list[dict] = field(default_factory=list)
    curves: list[RunCurves] = field(default_factory=list, repr=False, compare=False)
    estimator: list = field(default_factory=list)

    def parameter(self, name: str) -> ParameterEstimate:
        """The estimate called ``name``."""
        return next(p for p in self.parameters if p.name == name)

    def to_dict(self) -> dict:
        """JSON-ready dictionary (``tcamlab.jsonutil.dumps_json``), schema_version 1;
        without :attr:`curves`."""
        from tcamlab import __version__

        out = asdict(replace(self, curves=[], estimator=[]))
        del out["curves"]
        out["estimator"] = [f.to_dict() for f in self.estimator]
        return {"schema_version": SCHEMA_VERSION, "tool": f"tcamlab {__version__}", **out}
