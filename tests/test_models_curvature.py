"""Curvature (4.1) of the two-segment robot."""

import numpy as np
import pytest
from conftest import geometry

from tcamlab.models import curvature, sensing


def test_segment_curvature_hand_value():
    # C1 = 31 mm, C = 29 mm, d1 = 9 mm: kappa = 2 / (29 * 9) per mm
    assert curvature.segment_curvature(31e-3, 29e-3, 9e-3) == pytest.approx(
        2.0 / (29.0 * 9.0) * 1e3, rel=1e-14
    )


def test_circular_arcs_are_recovered(robot):
    sample, rig = robot
    d1 = rig.sensor_offset
    y_c = y_s = d1 / 2  # neutral axis midway between the cable and the sensor
    lengths = np.array(rig.segment_lengths)
    kappa_true = np.array([[0.0, 5.0, 12.0, 25.0], [0.0, 3.0, 8.0, 15.0]])  # 1/m, cable line
    kappa_n = kappa_true / (1 + kappa_true * y_c)  # neutral-axis curvature of the arcs
    elong = kappa_n * y_s * lengths[:, None]
    cable = (kappa_n * y_c * lengths[:, None]).sum(axis=0)
    kw = geometry(sample)
    r = np.empty_like(elong)
    for i, length in enumerate(lengths):
        ratio = length / sample.coil_length
        r[i] = sensing.forward(
            elong[i],
            rig.initial_resistance,
            rig.spring_constant,
            **dict(
                kw, fiber_length=kw["fiber_length"] * ratio, coil_length=length, twists=kw["twists"] * ratio
            ),
        )
    kappa, got_elong = curvature.curvatures(
        r, cable, [rig.initial_resistance] * 2, rig.spring_constant, d1, lengths, **kw
    )
    np.testing.assert_allclose(got_elong, elong, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(kappa, kappa_true, rtol=1e-8, atol=1e-9)


def test_cable_sharing_without_elongation():
    c = curvature.cable_lengths(np.zeros((2, 1)), [0.0], [0.03, 0.03])
    np.testing.assert_allclose(c[:, 0], [0.03, 0.03])
