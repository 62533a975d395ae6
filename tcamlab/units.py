"""The one table of logged quantities: internal name, CSV column, units, display factor.

Inside tcamlab every logged quantity is SI under a short internal name
(``displacement`` [m]); logs, reports, metrics and thresholds show it in lab
units under its canonical column name (``displacement_mm``). :data:`QUANTITIES`
is the single place that links the two; :mod:`tcamlab.io` builds its
``VARIABLE_MAP`` from it, and reports, metrics and the diagnosis take their
display units and factors from it.

:data:`PARAMETER_UNITS` does the same for the experiment file's sample and rig
keys, whose names carry their unit (``fiber_diameter_mm``).
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Quantity", "QUANTITIES", "PARAMETER_UNITS", "quantity", "display", "parameter_unit"]


@dataclass(frozen=True)
class Quantity:
    """One logged quantity.

    Attributes
    ----------
    name : str
        Internal (SI) column name, e.g. ``"displacement"``.
    column : str
        Canonical CSV column, its lab unit in its name, e.g. ``"displacement_mm"``.
    column_unit : str
        Unit of the canonical column in :data:`tcamlab.io.UNITS` spelling (``"per_mm"``).
    si_unit : str
        Unit inside tcamlab.
    factor : float
        Lab value = SI value * factor (``1e3`` from m to mm).
    """

    name: str
    column: str
    column_unit: str
    si_unit: str
    factor: float

    @property
    def unit(self) -> str:
        """The lab unit as printed in reports and axis labels (``"1/mm"`` for ``per_mm``)."""
        return self.column_unit.replace("per_", "1/")


def _q(name, column, column_unit, si_unit, factor) -> tuple[str, Quantity]:
    return name, Quantity(name, column, column_unit, si_unit, factor)


QUANTITIES: dict[str, Quantity] = dict(
    [
        _q("time", "time_s", "s", "s", 1.0),
        _q("temperature", "temperature_C", "degC", "degC", 1.0),
        _q("displacement", "displacement_mm", "mm", "m", 1e3),
        _q("voltage", "voltage_V", "V", "V", 1.0),
        _q("current", "current_A", "A", "A", 1.0),
        _q("resistance", "resistance_ohm", "ohm", "ohm", 1.0),
        _q("force", "force_N", "N", "N", 1.0),
        _q("load", "load_N", "N", "N", 1.0),
        _q("cable", "cable_mm", "mm", "m", 1e3),
        _q("r1", "r1_ohm", "ohm", "ohm", 1.0),
        _q("r2", "r2_ohm", "ohm", "ohm", 1.0),
        _q("kappa1", "kappa1_per_mm", "per_mm", "1/m", 1e-3),
        _q("kappa2", "kappa2_per_mm", "per_mm", "1/m", 1e-3),
    ]
)
"""Internal name -> :class:`Quantity`, in the order logs list them."""


PARAMETER_UNITS: dict[str, tuple[str, float]] = {
    # sample
    "fiber_diameter": ("mm", 1e3),
    "fiber_length": ("mm", 1e3),
    "coil_length": ("mm", 1e3),
    "coil_diameter": ("mm", 1e3),
    "twists": ("turns", 1.0),
    "youngs_modulus": ("GPa", 1e-9),
    "thread_plies": ("-", 1.0),
    "max_volume_fraction": ("-", 1.0),
    "radial_cte": ("1/K", 1.0),
    "shear_modulus_slope": ("MPa/K", 1e-6),
    # rig
    "load": ("g", 1e3),
    "ambient": ("degC", 1.0),
    "voltage": ("V", 1.0),
    "pulse": ("s", 1.0),
    "resistance": ("ohm", 1.0),
    "thermal_mass": ("J/K", 1.0),
    "heat_loss": ("W/K", 1.0),
    "damping": ("N s/m", 1.0),
    "initial_resistance": ("ohm", 1.0),
    "spring_constant": ("N/m", 1.0),
    "sensor_offset": ("mm", 1e3),
    "segment_lengths": ("mm", 1e3),
    "tcr": ("1/K", 1.0),
    "heater_tcr": ("1/K", 1.0),
    "lead_resistance": ("ohm", 1.0),
    "stretch_factor": ("-", 1.0),
    "tcr2": ("1/K^2", 1.0),
}
"""SI field of Sample or Rig -> (lab unit, factor from SI); the experiment file's key is
the field plus the unit (``coil_length_mm``, ``youngs_modulus_GPa``, ``load_g``)."""


def quantity(name: str) -> Quantity:
    """The :class:`Quantity` of an internal column name (KeyError if unknown)."""
    return QUANTITIES[name]


def display(name: str) -> tuple[str, float]:
    """(lab unit, factor from SI) of a quantity; ``("", 1.0)`` for a name not in the table."""
    q = QUANTITIES.get(name)
    return (q.unit, q.factor) if q is not None else ("", 1.0)


def parameter_unit(field: str) -> tuple[str, float]:
    """(lab unit, factor from SI) of a Sample or Rig field."""
    return PARAMETER_UNITS[field]
