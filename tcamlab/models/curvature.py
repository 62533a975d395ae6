"""Curvature of a two-segment soft robot from its embedded sensor, eq. (4.1).

Each segment i of the robot carries one part of the sensor (between two of the
three copper wires) at distance d1 from the pulling cable. Bent into a
circular arc, the sensor part and the cable part subtend the same angle, so
(4.1)

    kappa_i = (C1_i - C_i) / (C_i d1)

with C1_i the sensor length and C_i the cable length in the segment.

* C1_i = L_i + delta_i, with delta_i from the segment's resistance R_i by the
  sensing inversion of chapter 3 (:func:`tcamlab.models.sensing.invert`). A
  segment's sensor is the whole sensor cut in the ratio L_i / L: fiber length
  and twists scale with it; diameters, E and S per segment are as given.
* Cable length (our assumption; the thesis does not say how C is obtained):
  the logged cable pull-in c is shared between the segments in proportion to
  their sensor elongations, C_i = L_i - c delta_i / sum_j delta_j. This holds
  exactly for circular arcs when the neutral axis sits at the same place in
  both segments (the sensor and cable are placed symmetrically in the mould,
  section 4.3): each segment's cable shortening is then a fixed multiple of
  its sensor elongation. With no elongation (sum delta = 0) each C_i = L_i.
"""

from __future__ import annotations

import numpy as np

from tcamlab.errors import ModelDomainError
from tcamlab.models import sensing as _sensing

__all__ = ["segment_curvature", "cable_lengths", "curvatures"]


def segment_curvature(sensor_length, cable_length, sensor_offset):
    """Curvature of one segment, eq. (4.1): kappa = (C1 - C) / (C d1).

    Parameters
    ----------
    sensor_length : array_like
        C1 [m].
    cable_length : array_like
        C [m].
    sensor_offset : float
        d1 [m].

    Returns
    -------
    ndarray
        kappa [1/m].
    """
    c = np.asarray(cable_length, float)
    return (np.asarray(sensor_length, float) - c) / (c * float(sensor_offset))


def cable_lengths(elongations, cable, segment_lengths):
    """Cable length per segment under the proportional-sharing assumption.

    Parameters
    ----------
    elongations : array_like, shape (k, n)
        Sensor elongation delta_i of each of k segments [m].
    cable : array_like, shape (n,)
        Cable pull-in c [m] (positive when pulled).
    segment_lengths : sequence of k floats
        Rest lengths L_i [m].

    Returns
    -------
    ndarray, shape (k, n)
        C_i [m].
    """
    e = np.asarray(elongations, float)
    lengths = np.asarray(segment_lengths, float)[:, None]
    total = e.sum(axis=0)
    safe = np.where(np.abs(total) > 0, total, 1.0)
    share = np.where(np.abs(total) > 0, e / safe, lengths / lengths.sum())
    return lengths - np.asarray(cable, float) * share


def curvatures(
    resistances,
    cable,
    initial_resistances,
    spring_constant,
    sensor_offset,
    segment_lengths,
    fiber_diameter,
    fiber_length,
    coil_length,
    coil_diameter,
    twists,
    youngs_modulus,
    thread_plies=2,
    max_volume_fraction=0.887,
):
    """Segment curvatures from segment resistances, eqs. (3.1)-(3.7) and (4.1).

    Parameters
    ----------
    resistances : array_like, shape (k, n)
        R_i of each segment [ohm] (k = 2 for the thesis robot).
    cable : array_like, shape (n,)
        Cable pull-in [m].
    initial_resistances : sequence of k floats
        R0_i [ohm].
    spring_constant : float
        S of one segment's sensor [N/m].
    sensor_offset : float
        d1 [m].
    segment_lengths : sequence of k floats
        L_i [m]; their sum is the sensor's coil length.
    fiber_diameter, fiber_length, coil_length, coil_diameter, twists, youngs_modulus,
    thread_plies, max_volume_fraction :
        The whole embedded sensor (SI), as in :func:`tcamlab.models.sensing.invert`.

    Returns
    -------
    kappa : ndarray, shape (k, n)
        Curvatures [1/m].
    elongation : ndarray, shape (k, n)
        Sensor elongations delta_i [m].
    """
    res = np.atleast_2d(np.asarray(resistances, float))
    lengths = np.asarray(segment_lengths, float)
    if res.shape[0] != lengths.size or len(initial_resistances) != lengths.size:
        raise ModelDomainError(
            f"curvature model: {res.shape[0]} resistance series for {lengths.size} segments",
            hint="segment_lengths_mm needs one length per resistance column",
        )
    if abs(lengths.sum() - coil_length) > 1e-6 * coil_length:
        raise ModelDomainError(
            f"curvature model: segment lengths sum to {lengths.sum() * 1e3:g} mm but the "
            f"sensor is {coil_length * 1e3:g} mm long",
            hint="segment_lengths_mm must add up to coil_length_mm",
        )
    elong = np.empty_like(res)
    for i, length in enumerate(lengths):
        ratio = length / coil_length
        elong[i], _ = _sensing.invert(
            res[i],
            initial_resistances[i],
            spring_constant,
            fiber_diameter,
            fiber_length * ratio,
            length,
            coil_diameter,
            twists * ratio,
            youngs_modulus,
            thread_plies,
            max_volume_fraction,
        )
    cab = cable_lengths(elong, cable, lengths)
    kappa = segment_curvature(lengths[:, None] + elong, cab, sensor_offset)
    return kappa, elong
