"""Models against tests/data/reference_values.json, an independent scalar
implementation of the same equations (tests/data/make_reference.py)."""

import json
from pathlib import Path

import numpy as np
import pytest

from tcamlab.models import sensing, static

REF = json.loads((Path(__file__).parent / "data/reference_values.json").read_text())
T = REF["tca"]
S = REF["tcs"]


def tca_kwargs():
    return dict(
        fiber_diameter=T["d0"],
        fiber_length=T["length"],
        coil_length=T["L"],
        coil_diameter=T["D"],
        twists=T["turns"],
        youngs_modulus=T["E"],
        thread_plies=T["plies"],
        max_volume_fraction=T["vfmax"],
        radial_cte=T["rho"],
    )


def test_shear_modulus_and_torque():
    g = static.sample_shear_modulus(T["d0"], T["length"], T["turns"], T["E"], T["plies"], T["vfmax"])
    assert g == pytest.approx(REF["shear_modulus_tca"], rel=1e-13)
    assert static.torque(100.0, g, T["d0"], T["turns"], T["length"], T["rho"]) == pytest.approx(
        REF["torque_tca_100K"], rel=1e-12
    )


def test_compliances():
    g = REF["shear_modulus_tca"]
    for p in REF["pieces"]:
        f11, f12 = static.compliances(p["s"], 0.17e-3, 0.095, 82.0, g, 3.45e9)
        assert f11 == pytest.approx(p["f11"], rel=1e-13)
        assert f12 == pytest.approx(p["f12"], rel=1e-13, abs=1e-18)


@pytest.mark.parametrize("method", ["jit", "numpy"])
def test_static_displacement(method):
    rows = REF["static"]
    for slope in (0.0, 1.11e6):
        sel = [r for r in rows if r["slope"] == slope]
        got = static.displacement(
            np.array([r["dT"] for r in sel]),
            np.array([r["F"] for r in sel]),
            **tca_kwargs(),
            shear_modulus_slope=slope,
            method=method,
        )
        np.testing.assert_allclose(got, [r["delta"] for r in sel], rtol=1e-10, atol=1e-14)


def test_sensing_inversion():
    rows = REF["sensing"]
    got, force = sensing.invert(
        np.array([r["R"] for r in rows]),
        30.0,
        4.7,
        fiber_diameter=S["d0"],
        fiber_length=S["length"],
        coil_length=S["L"],
        coil_diameter=S["D"],
        twists=S["turns"],
        youngs_modulus=S["E"],
        thread_plies=S["plies"],
        max_volume_fraction=S["vfmax"],
    )
    expected = np.array([r["delta"] for r in rows])
    np.testing.assert_allclose(got, expected, rtol=1e-10)
    np.testing.assert_allclose(force, 4.7 * expected, rtol=1e-10)
