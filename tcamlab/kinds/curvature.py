"""Camera curvature test of the two-segment robot (thesis section 4.3).

R1 and R2 give each segment's sensor elongation by the sensing inversion of
chapter 3; with the cable pull they give the segment curvatures by (4.1).
Effect terms of :class:`tcamlab.effects.Mods` that act here: compression,
camera_offset, offset_error.

The per-run rule (:func:`run_options`), shared by validation, diagnosis and
the virtual rig: S is the rig's (one segment; it must be stated), and each
segment's R0 is the rig's ``initial_resistance`` if stated, else the mean of
that channel over the run's leading rows at rest.

The virtual rig's camera test (:func:`protocol`, :func:`exact_inputs`,
:func:`measure`): with both lines at d1/2 from the neutral axis, a pull c
bends segment i (length L_i, tip first) to kappa_i with
sum_i kappa_i (d1/2) L_i = c and kappa_tip / kappa_base =
:data:`TIP_TO_BASE_CURVATURE`; the sensor part stretches by
delta_i = kappa_i (d1/2) L_i and reads R_i = sensing.forward(delta_i) for a
segment sensor whose fiber length and twists are the whole sensor's scaled
by L_i / L (S = rig.spring_constant). The camera's ground truth is
:func:`predict` of the exact R_i and cable, so the model is exact without
effects.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from tcamlab import instruments
from tcamlab.effects import NO_MODS, Mods
from tcamlab.errors import ConfigError, InputError, ModelDomainError
from tcamlab.kinds import CalibrationParam, Kind, RunOptions, no_extras, no_section, rest_rows, stated_source
from tcamlab.models import curvature as _curv
from tcamlab.models import sensing as _sens
from tcamlab.params import THESIS_ROBOT, Rig, Sample
from tcamlab.report.document import Figure
from tcamlab.report.figures import legend_label, new_figure

CABLE_STEP_M = 1e-3
"""Cable pull step of the actuator [m]."""
CABLE_MAX_M = 10e-3
"""Largest cable pull [m]: 11 poses."""
TIP_TO_BASE_CURVATURE = 1.5
"""Assumed ratio of tip to base segment curvature [-]: the tip (EcoFlex 00-10) is
softer than the base (00-30) and the cable's bending moment is the same in
both, so curvature goes with compliance; 1.5 is a round ratio between the two
grades' moduli."""


def predict(
    sample: Sample,
    rig: Rig,
    data: pd.DataFrame,
    mods: Mods = NO_MODS,
    *,
    spring_constant: float,
    initial_resistances: tuple[float, float],
) -> dict[str, np.ndarray]:
    """Camera test: segment curvatures from R1, R2 and the cable, (4.1).

    Parameters
    ----------
    data : DataFrame
        ``cable`` [m], ``r1``, ``r2`` [ohm].
    spring_constant : float
        S of one segment [N/m].
    initial_resistances : (float, float)
        R0 of each segment [ohm].
    mods : Mods
        compression, camera_offset, offset_error.

    Returns
    -------
    dict
        ``kappa1``, ``kappa2`` [1/m].
    """
    kw = sample.sensor_kwargs()
    lengths = np.asarray(rig.segment_lengths, float)
    res = np.vstack([data["r1"].to_numpy(float), data["r2"].to_numpy(float)])
    cable = data["cable"].to_numpy(float)
    _, elong = _curv.curvatures(
        res, cable, initial_resistances, spring_constant, rig.sensor_offset, lengths, **kw
    )
    # Axial compression: a fraction a of the pull-in shortens the whole body
    # (cable and sensor lines alike) instead of bending it. The sensor length
    # from R already includes it; the bending share of each segment is its
    # sensor elongation plus the squeeze.
    squeeze = mods.compression * cable * lengths[:, None] / lengths.sum()
    bend = _curv.cable_lengths(elong + squeeze, (1.0 - mods.compression) * cable, lengths)
    cab = bend - squeeze
    d1 = rig.sensor_offset + mods.offset_error
    if d1 <= 0:
        raise ModelDomainError("curvature model: sensor offset d1 must stay positive")
    kappa = _curv.segment_curvature(lengths[:, None] + elong, cab, d1)
    kappa = kappa + mods.camera_offset
    return {"kappa1": kappa[0], "kappa2": kappa[1]}


def initial_resistances(rig: Rig, data: pd.DataFrame, provenance=None) -> tuple[tuple[float, float], str]:
    """R0 of each segment [ohm] and where they came from (the module's rule)."""
    r0 = rig.initial_resistance
    if r0 is not None:
        pair = tuple(float(x) for x in r0) if isinstance(r0, tuple) else (float(r0), float(r0))
        return pair, stated_source(provenance, "initial_resistance")
    rows = rest_rows(KIND, data)
    pair = tuple(float(data[c].to_numpy(float)[rows].mean()) for c in ("r1", "r2"))
    return pair, "first row of the run" if rows.size == 1 else f"mean of the {rows.size} rows at rest"


def run_options(
    sample: Sample, rig: Rig, data: pd.DataFrame, *, where: str = "", provenance=None, **_
) -> RunOptions:
    """S (stated in the rig) and each segment's R0 by the module's rule."""
    if rig.spring_constant is None:
        raise InputError(
            f"{where}: curvature validation needs the sensor's spring constant",
            hint="set spring_constant_N_per_m in [rig] (one segment)",
        )
    r0s, source = initial_resistances(rig, data, provenance)
    options = {"spring_constant": float(rig.spring_constant), "initial_resistances": r0s}
    return RunOptions(options, {"initial_resistances_ohm": r0s, "initial_resistances_source": source})


def regimes(data: pd.DataFrame, quantity: str, frames=()) -> dict[str, np.ndarray]:
    """Low or high bend (below or above the middle cable pull) of the quantity's segment."""
    c = data["cable"].to_numpy(float)
    mid = 0.5 * (np.nanmin(c) + np.nanmax(c))
    seg = "segment 1" if quantity == "kappa1" else "segment 2"
    labels = np.where(c <= mid, f"{seg}, low bend", f"{seg}, high bend").astype(object)
    return {"segment x bending": labels}


def figures(result) -> list[Figure]:
    """Segment curvatures against cable pull, as thesis figure 4.8."""
    fig, ax = new_figure()
    for p in result.predictions:
        c = p.data["cable"].to_numpy() * 1e3
        name = legend_label(p.name)
        for q, marker in (("kappa1", "o"), ("kappa2", "s")):
            (line,) = ax.plot(c, p.data[q] * 1e-3, marker, ms=3, label=f"{name} {q} camera")
            ax.plot(
                c,
                p.predicted["thesis"][q] * 1e-3,
                "-",
                color=line.get_color(),
                lw=1,
                label=f"{name} {q} model",
            )
    ax.set_xlabel("cable pull [mm]")
    ax.set_ylabel("curvature [1/mm]")
    ax.legend(fontsize=6, ncol=2)
    caption = (
        "Segment curvatures against cable pull: camera (markers) and model from R1, R2 "
        "(lines), as in thesis figure 4.8."
    )
    return [Figure(fig, caption, alt="curvature plot")]


# --- virtual rig ---------------------------------------------------------------------------


def protocol(rig: Rig, rng: np.random.Generator) -> pd.DataFrame:
    """The exact cable program of one run (deterministic; ``rig`` and ``rng`` are unused).

    Returns
    -------
    pandas.DataFrame
        ``cable`` [m]: 0 to :data:`CABLE_MAX_M` in :data:`CABLE_STEP_M` steps.
    """
    n = int(round(CABLE_MAX_M / CABLE_STEP_M)) + 1
    return pd.DataFrame({"cable": np.arange(n) * CABLE_STEP_M})


def segment_curvatures(cable: np.ndarray, rig: Rig) -> np.ndarray:
    """Neutral-axis curvature of each segment (tip first) for a cable pull [1/m].

    Parameters
    ----------
    cable : ndarray
        Cable pull [m].
    rig : Rig
        ``segment_lengths`` [m] and ``sensor_offset`` d1 [m] (cable at d1/2).

    Returns
    -------
    ndarray, shape (segments, len(cable))
        kappa_i [1/m], tip / base = :data:`TIP_TO_BASE_CURVATURE`.
    """
    lengths = np.asarray(rig.segment_lengths, float)
    ratio = np.ones(lengths.size)
    ratio[0] = TIP_TO_BASE_CURVATURE
    y_c = rig.sensor_offset / 2.0
    base = cable / (y_c * float(np.sum(ratio * lengths)))
    return ratio[:, None] * base[None, :]


def exact_inputs(sample: Sample, rig: Rig, proto: pd.DataFrame, mods: Mods = NO_MODS) -> pd.DataFrame:
    """The cable pull and each segment's exact resistance, from the geometry of the module docstring.

    Returns
    -------
    pandas.DataFrame
        ``cable`` [m], ``r1``, ``r2`` [ohm].
    """
    if rig.spring_constant is None or rig.initial_resistance is None:
        raise ConfigError(
            "curvature simulation needs spring_constant_N_per_m and initial_resistance_ohm in the template's [rig]"
        )
    cable = proto["cable"].to_numpy(float)
    lengths = np.asarray(rig.segment_lengths, float)
    if lengths.size != 2:
        raise ConfigError(
            "the curvature rig simulates a two-segment robot", hint="segment_lengths_mm = [tip, base]"
        )
    elong = segment_curvatures(cable, rig) * (rig.sensor_offset / 2.0) * lengths[:, None]
    r0s, _ = initial_resistances(rig, proto)
    kw = sample.sensor_kwargs()
    out = {"cable": cable}
    for i, length in enumerate(lengths):
        # A segment's sensor: the whole sensor's fiber and twists scaled by L_i / L.
        ratio = length / sample.coil_length
        out[f"r{i + 1}"] = _sens.forward(
            elong[i],
            r0s[i],
            rig.spring_constant,
            kw["fiber_diameter"],
            kw["fiber_length"] * ratio,
            length,
            kw["coil_diameter"],
            kw["twists"] * ratio,
            kw["youngs_modulus"],
            kw["thread_plies"],
            kw["max_volume_fraction"],
        )
    return pd.DataFrame(out)


def instrument_sd(noise_scale: float = 1.0) -> dict[str, float]:
    """Sd of each logged column's chain [SI]: programmed cable exact, two multimeter channels, camera."""
    ohm = instruments.ohmmeter_sd(noise_scale)
    cam = instruments.camera_sd(noise_scale)
    return {"cable": 0.0, "r1": ohm, "r2": ohm, "kappa1": cam, "kappa2": cam}


def measure(
    inputs: pd.DataFrame, outputs: dict, rng: np.random.Generator, noise_scale: float, *, noisy_zero=False
) -> pd.DataFrame:
    """Logged ``cable`` [m] (exact), ``r1``, ``r2`` [ohm] (multimeter), ``kappa1``, ``kappa2`` [1/m] (camera).

    ``noisy_zero`` changes nothing here: the camera measures absolute
    curvature and no channel is zeroed on the run (``attrs["zero_error"]`` is empty).
    """
    out = {"cable": inputs["cable"].to_numpy(float)}
    for c in ("r1", "r2"):
        out[c] = instruments.ohmmeter(inputs[c].to_numpy(float), rng, noise_scale)
    for q in ("kappa1", "kappa2"):
        out[q] = instruments.camera(np.asarray(outputs[q], float), rng, noise_scale)
    return pd.DataFrame(out)


CALIBRATION = (
    CalibrationParam(
        "sensor_offset", "rig", "d1", "m", 0.2, "a bend of known curvature (e.g. around a mandrel)"
    ),
    CalibrationParam("spring_constant", "rig", "S", "N/m", 0.5, "a sensing pull test of the embedded sensor"),
    # At zero cable the body is straight and both sensors are at rest length, so the
    # ohmmeters read R0 there: the rows at rest measure it (read_at_rest). Left to its 5 %
    # prior, R0 shifted by 0.3-0.8 % turned a constant camera offset into axial
    # compression and back (both fit the withheld runs within noise).
    CalibrationParam(
        "initial_resistance",
        "rig",
        "R0",
        "ohm",
        0.05,
        "more rows at rest before the cable is pulled",
        read_at_rest=("r1", "r2"),
    ),
    # The camera logs pin S and E only as their ratio (posterior correlation +0.9; S
    # absorbed E's error when E was fixed), so E is calibrated with its prior and S's
    # interval carries E's uncertainty.
    CalibrationParam("youngs_modulus", "sample", "E", "Pa", 0.2, "a tensile test of the straight fiber"),
)
"""Calibratable parameters of the camera curvature test (one S and R0 for both segments;
E, which the logs pin only together with S, as S/E)."""


KIND = Kind(
    name="curvature",
    description="camera curvature test (thesis section 4.3): segment curvatures predicted from R1, R2 by (4.1)",
    required_columns=("cable_mm", "r1_ohm", "r2_ohm", "kappa1_per_mm", "kappa2_per_mm"),
    optional_columns=("time_s",),
    min_rows=2,
    inputs=("cable", "r1", "r2"),
    outputs=("kappa1", "kappa2"),
    tension_outputs=(),
    variants={"thesis": {}},
    predict=predict,
    run_options=run_options,
    needs_training=False,
    validation_extras=no_extras,
    x_column="cable",
    regimes=regimes,
    # r1, r2 are measured responses of the commanded cable, so only the cable counts.
    shared_inputs=("cable",),
    report_rig_fields=(
        "ambient",
        "initial_resistance",
        "spring_constant",
        "sensor_offset",
        "segment_lengths",
    ),
    figures=figures,
    extras_section=no_section,
    preset=THESIS_ROBOT,
    logged_columns=("cable", "r1", "r2", "kappa1", "kappa2"),
    decimals={
        "cable_mm": 2,
        "r1_ohm": 3,
        "r2_ohm": 3,
        "kappa1_per_mm": 6,
        "kappa2_per_mm": 6,
    },
    written_rig_fields=(
        "ambient",
        "initial_resistance",
        "spring_constant",
        "sensor_offset",
        "segment_lengths",
    ),
    hidden_rig_fields=(),
    default_runs=3,
    default_scatter={"twists": 5e-4, "coil_length": 5e-4},
    noisy_inputs=("r1", "r2"),
    strength_quantities=("kappa1", "kappa2"),
    protocol=protocol,
    benchmark_program={},
    # 10 % of E; 0.3 mm of d1 (a mould tolerance on 9 mm)
    benchmark_uncertainty={"youngs_modulus": 0.345e9, "sensor_offset": 0.3e-3},
    benchmark_pairs=(("camera-placement", "axial-compression"),),
    program_options=(),
    exact_inputs=exact_inputs,
    instrument_sd=instrument_sd,
    measure=measure,
    simulation_rig_defaults={},
    # One R0 per segment; the embedded sensor spans the segments, so they
    # change length with its coil length.
    segment_rig_fields=("initial_resistance",),
    coil_length_rig_fields=("segment_lengths",),
    calibration=CALIBRATION,
    nuisance_zeros=(),
)
