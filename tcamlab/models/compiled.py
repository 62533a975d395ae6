"""The thesis equations compiled once with numba, for every kernel that needs them.

Each name is ``numba.njit`` applied to the one Python function the rest of
tcamlab uses, so the dynamic solver and the self-sensing observer share both the
implementation and the compiled code. Numba's disk cache does not notice edits
to the wrapped modules: touch this file (and the kernels) after changing them.
Imported lazily by the kernels, so JIT cost stays out of ``--help``.
"""

from __future__ import annotations

from numba import njit

from tcamlab.models import coil, dynamic, static, thermal

heating_rate = njit(cache=True)(thermal.heating_rate)  # (2.18)
softened_modulus = njit(cache=True)(static.softened_modulus)  # (2.13)
torque_from_strain = njit(cache=True)(static.torque_from_strain)  # (2.9)
compliance_coefficients = njit(cache=True)(coil.compliance_coefficients)  # (2.11)
compliance_terms = njit(cache=True)(coil.compliance_terms)  # (2.11)
restoring_force = njit(cache=True)(coil.restoring_force)  # (2.15)
acceleration = njit(cache=True)(dynamic.acceleration)  # (2.19)
youngs_modulus_at = njit(cache=True)(static.youngs_modulus_at)  # E(T) of the effect library
pitch_residual = njit(cache=True)(static.pitch_residual)  # (2.10) = (2.11)
