"""Regenerate tests/data/reference_values.json: the thesis equations written
out independently, point by point, with the math module and scipy's brentq.

Run: python tests/data/make_reference.py
Nothing here imports tcamlab, so the models are checked against a second,
plain implementation of the same equations.
"""

import json
import math
from pathlib import Path

from scipy.optimize import brentq

G_ACCEL = 9.80665


def shear_modulus(E, plies, vfmax, d0, turns, length):
    vf = vfmax / plies**2
    af = math.atan(math.pi * d0 * turns / length)
    c = math.cos(af)
    num = 4 * vf * E * (af / 2 - math.sin(2 * af) / 4) ** 2
    den = math.pi * (2 + math.pi) * (2 / 3 - c + c**3 / 3) * (1 - c)
    return num / den


def torque(G, d0, d, turns, length):
    J = math.pi * d**4 / 32
    return G * J * 2 * math.pi * turns * (1 - d0 / d) / length


def f11_f12(s, d, length, n, G, E):
    c2 = 1 - s * s
    s2 = s * s
    ln = length / n
    f11 = (
        8 * n / (math.pi**3 * d**4) * ln**3 * c2 * c2 / G
        + 8 * n / (math.pi * d**2) * ln * c2 / (2 * G)
        + 8 * n / (math.pi**3 * d**4) * ln**3 * 2 * s2 * c2 / E
        + 8 * n / (math.pi * d**2) * ln * s2 / (2 * E)
    )
    f12 = 8 * n / (math.pi**2 * d**4) * ln**2 * c2 / G
    return f11, f12


def static_displacement(dT, F, d0, length, L, D, turns, E, plies, vfmax, rho, slope):
    G = shear_modulus(E, plies, vfmax, d0, turns, length)
    s0 = L / length
    n = length * math.sqrt(1 - s0**2) / (math.pi * D)
    d = d0 * (1 + rho * dT)
    tau = torque(G - slope * dT, d0, d, turns, length)

    def h(s):
        f11, f12 = f11_f12(s, d, length, n, G, E)
        return length * (s - s0) - (f11 * F - f12 * tau)

    s = brentq(h, 0.0, 1.0, xtol=1e-15, rtol=1e-15)
    return length * (s - s0)


def sensing_delta(R, R0, S, d0, length, L, D, turns, E, plies, vfmax):
    G = shear_modulus(E, plies, vfmax, d0, turns, length)
    s0 = L / length
    n = length * math.sqrt(1 - s0**2) / (math.pi * D)
    d = d0 * math.sqrt(R0 / R)
    tau = torque(G, d0, d, turns, length)

    def h(delta):
        f11, f12 = f11_f12(s0 + delta / length, d, length, n, G, E)
        return delta * (1 - S * f11) + f12 * tau

    return brentq(h, 0.0, length * (1 - s0) * (1 - 1e-12), xtol=1e-18, rtol=1e-15)


TCA = dict(
    d0=0.17e-3, length=0.095, L=0.020, D=0.36e-3, turns=150.0, E=3.45e9, plies=2, vfmax=0.887, rho=8.1e-5
)
TCS = dict(d0=0.4e-3, length=0.328, L=0.090, D=0.8e-3, turns=750.0, E=3.45e9, plies=2, vfmax=0.887)


def main():
    out = {"tca": TCA, "tcs": TCS, "static": [], "sensing": [], "pieces": []}
    for dT in (0.0, 10.0, 55.0, 100.0, 130.0):
        for F in (0.0, 0.05 * G_ACCEL, 0.8):
            for slope in (0.0, 1.11e6):
                out["static"].append(
                    {
                        "dT": dT,
                        "F": F,
                        "slope": slope,
                        "delta": static_displacement(dT, F, slope=slope, **TCA),
                    }
                )
    for R in (30.05, 30.5, 31.0, 31.7):
        out["sensing"].append({"R": R, "R0": 30.0, "S": 4.7, "delta": sensing_delta(R, 30.0, 4.7, **TCS)})
    G = shear_modulus(3.45e9, 2, 0.887, 0.17e-3, 150.0, 0.095)
    for s in (0.0, 0.21, 0.5, 0.9):
        f11, f12 = f11_f12(s, 0.17e-3, 0.095, 82.0, G, 3.45e9)
        out["pieces"].append({"s": s, "f11": f11, "f12": f12})
    out["shear_modulus_tca"] = G
    out["torque_tca_100K"] = torque(G, 0.17e-3, 0.17e-3 * (1 + 8.1e-5 * 100), 150.0, 0.095)
    path = Path(__file__).with_name("reference_values.json")
    path.write_text(json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    main()
