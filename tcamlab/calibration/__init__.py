"""Calibration: the kinds' parameters identified from the logs, with intervals and words.

:func:`calibrate` fits, jointly over every run of one or more experiments of one
sample, the parameters each kind lists in :attr:`tcamlab.kinds.Kind.calibration`
(dynamic C_th, lambda, b, rho, G_t slope and R where a current or resistance is logged; static
rho, G_t slope, E; sensing S, R0, E; curvature
d1, S, R0). It maximises the posterior: the stacked residuals
``(measured - predicted - zero) / sigma`` of every run and quantity, with each
run's zero of a zero-referenced quantity a flat-prior nuisance
(:attr:`~tcamlab.kinds.Kind.nuisance_zeros`) and ``sigma`` the noise floor from
second differences, plus Gaussian priors from ``[rig.uncertainty]`` and
``[sample.uncertainty]`` (in log space for positive parameters; a documented
default sd where none is stated). It reports Laplace and profile-likelihood
95 % intervals, the correlation matrix and which parameters or combinations
the data pin down (:mod:`tcamlab.calibration.identify`).

This package imports neither :mod:`tcamlab.diagnosis` nor :mod:`tcamlab.rig`:
the diagnosis builds on it.

Example
-------
>>> from tcamlab.calibration import calibrate
>>> result = calibrate(["experiments/dynamic.toml"])  # doctest: +SKIP
>>> result.parameter("thermal_mass").profile_95  # doctest: +SKIP
"""

from tcamlab.calibration.calibrated_file import calibrated_document, calibrated_path, calibrated_text
from tcamlab.calibration.core import calibrate, load_experiments
from tcamlab.calibration.result import CalibrationResult, FitQuality, ParameterEstimate, ZeroEstimate

__all__ = [
    "calibrate",
    "load_experiments",
    "calibrated_document",
    "calibrated_path",
    "calibrated_text",
    "CalibrationResult",
    "ParameterEstimate",
    "ZeroEstimate",
    "FitQuality",
]
