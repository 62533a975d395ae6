"""Camera curvature test of the two-segment robot (thesis section 4.3).

R1 and R2 give each segment's sensor elongation by the sensing inversion of
chapter 3; with the cable pull they give the segment curvatures by (4.1).
Effect terms of :class:`tcamlab.effects.Mods` that act here: compression,
camera_offset, offset_error.

The per-run rule (:func:`run_options`), shared by validation, diagnosis and
the virtual rig: S is the rig's (one segment; it must be stated), and each
segment's R0 is the rig's ``initial_resistance`` if stated, else the mean of
that channel over the run's rows at rest, those at its smallest cable pull
wherever they are in the log (:func:`rest_rows`: the log has no time, so its rows
need not come in pull order). The robot's geometry is checked first
(:func:`check_geometry`).

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

from dataclasses import replace

import numpy as np
import pandas as pd

from tcamlab import instruments
from tcamlab.effects import NO_MODS, Mods
from tcamlab.errors import ConfigError, InputError, ModelDomainError
from tcamlab.kinds import (
    REST_TOLERANCE,
    CalibrationParam,
    Kind,
    RunOptions,
    no_extras,
    no_section,
    stated_source,
)
from tcamlab.kinds import protocol_values as pv
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
    initial_resistances: tuple[float, float] | None = None,
    initial_resistance: float | None = None,
) -> dict[str, np.ndarray]:
    """Camera test: segment curvatures from R1, R2 and the cable, (4.1).

    Parameters
    ----------
    data : DataFrame
        ``cable`` [m], ``r1``, ``r2`` [ohm].
    spring_constant : float
        S of one segment [N/m].
    initial_resistances : (float, float), optional
        R0 of each segment [ohm].
    initial_resistance : float, optional
        One R0 of both segments [ohm], used only without ``initial_resistances``
        (:func:`run_options` gives both: this one is the R0 calibration fits).
    mods : Mods
        compression, camera_offset, offset_error.

    Returns
    -------
    dict
        ``kappa1``, ``kappa2`` [1/m].
    """
    if "r1" not in data or "r2" not in data:
        raise InputError(
            "curvature model: no r1, r2 columns (a cable program, not a log)",
            hint="the resistances a program gives come from tcamlab.kinds.curvature.exact_inputs",
        )
    if initial_resistances is None:
        if initial_resistance is None:
            raise TypeError("curvature predict needs initial_resistances or initial_resistance")
        initial_resistances = (float(initial_resistance),) * 2
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


def rest_rows(data: pd.DataFrame, at: str = "") -> np.ndarray:
    """Indices of the rows at rest: the run's smallest cable pull |c| [m], within
    :data:`tcamlab.kinds.REST_TOLERANCE` of the pulls' range.

    The log has no time column, so the rows need not come in pull order: the rest reference
    is the slack cable wherever its rows are, not the leading rows.

    Raises
    ------
    InputError
        When the smallest pull is more than :data:`tcamlab.kinds.REST_TOLERANCE` of the
        largest (no row is at rest; ``at`` prefixes the message).
    """
    cable = np.abs(data["cable"].to_numpy(float))
    finite = cable[np.isfinite(cable)]
    top = float(finite.max()) if finite.size else np.nan
    low = float(finite.min()) if finite.size else np.nan
    if not low <= REST_TOLERANCE * top:
        row = int(np.nanargmin(cable)) + 1 if finite.size else 0
        raise InputError(
            f"{at}curvature run: no row at rest, so R0 cannot be read: its smallest cable pull is "
            f"{low * 1e3:.4g} mm (data row {row}), more than {REST_TOLERANCE:.0%} of its largest, "
            f"{top * 1e3:.4g} mm",
            hint="state initial_resistance_ohm in [rig] (each segment's resistance with the cable "
            "slack), or log a row at zero cable pull",
        )
    return np.flatnonzero(cable - low <= REST_TOLERANCE * (top - low))


def initial_resistances(
    rig: Rig, data: pd.DataFrame, provenance=None, at: str = ""
) -> tuple[tuple[float, float], str]:
    """R0 of each segment [ohm] and where they came from (the module's rule): the rig's
    ``initial_resistance`` if stated, else the mean of r1, r2 over the rows at rest
    (:func:`rest_rows`; ``at`` prefixes its error)."""
    r0 = rig.initial_resistance
    if r0 is not None:
        pair = tuple(float(x) for x in r0) if isinstance(r0, tuple) else (float(r0), float(r0))
        return pair, stated_source(provenance, "initial_resistance")
    rows = rest_rows(data, at)
    pair = tuple(float(data[c].to_numpy(float)[rows].mean()) for c in ("r1", "r2"))
    return pair, "the row at rest" if rows.size == 1 else f"mean of the {rows.size} rows at rest"


SEGMENTS = 2
"""Segments of the camera rig's robot [-]: one per logged resistance column (r1, r2)."""


def check_geometry(sample: Sample, rig: Rig, at: str = "") -> None:
    """Refuse a robot geometry the camera test's model cannot read, naming the key.

    * ``segment_lengths`` [m]: one length per resistance column (:data:`SEGMENTS`), adding up
      to the sensor's ``coil_length`` [m], which the segments split.
    * ``sensor_offset`` d1 [m]: above the sensor coil's radius D/2 (the cable runs beside
      the coil, not inside it) and below the shortest segment: (4.1) takes each segment as a
      circular arc of a slender body, and a body thicker than a segment is long does not bend
      as one (thesis robot: d1 = 9 mm in a 60 x 12 x 10 mm body of two 30 mm segments).

    Raises
    ------
    ConfigError
        Naming the ``[rig]`` key, with a hint of valid values.
    """
    lengths = np.asarray(rig.segment_lengths, float)
    coil = sample.coil_length
    halves = f"segment_lengths_mm = [{coil * 500:g}, {coil * 500:g}]"
    shown = "[" + ", ".join(f"{x * 1e3:g}" for x in lengths) + "]"
    if lengths.size != SEGMENTS:
        raise ConfigError(
            f"{at}rig.segment_lengths_mm = {shown}: {lengths.size} segment(s), but a curvature run "
            f"logs {SEGMENTS} resistance series (r1_ohm, r2_ohm)",
            hint=f"one length per segment, tip first, e.g. {halves}",
        )
    if abs(lengths.sum() - coil) > 1e-6 * coil:
        raise ConfigError(
            f"{at}rig.segment_lengths_mm = {shown}: the segment lengths sum to {lengths.sum() * 1e3:g} mm "
            f"but the sensor (sample coil_length_mm) is {coil * 1e3:g} mm long",
            hint=f"the segments split the embedded sensor, e.g. {halves}",
        )
    _check_offset(sample, rig, lengths, at)


def _check_offset(sample: Sample, rig: Rig, lengths: np.ndarray, at: str) -> None:
    """Refuse d1 [m] outside (D/2, shortest segment) (:func:`check_geometry`)."""
    lo, hi = sample.coil_diameter / 2.0, float(lengths.min())
    d1 = rig.sensor_offset
    if not lo < d1 < hi:
        raise ConfigError(
            f"{at}rig.sensor_offset_mm = {d1 * 1e3:g} is outside {lo * 1e3:g} to {hi * 1e3:g} mm: d1 must "
            "exceed the sensor coil's radius (sample coil_diameter_mm / 2) and stay below the shortest "
            "segment (a slender body)",
            hint=f"the distance from the sensor to the cable in mm (the thesis robot: 9), e.g. "
            f"sensor_offset_mm = {float(np.clip(9.0, lo * 1e3 * 1.01, hi * 1e3 * 0.99)):.3g}",
        )


def run_options(
    sample: Sample, rig: Rig, data: pd.DataFrame, *, where: str = "", provenance=None, **_
) -> RunOptions:
    """S (stated in the rig) and each segment's R0 by the module's rule, after the robot's
    geometry (:func:`check_geometry`); ``where`` (the experiment file) prefixes the errors.

    The options also carry ``initial_resistance``, the mean of the segments' R0 [ohm]: the
    one R0 calibration fits, which starts there when the file leaves it unstated.
    """
    at = f"{where}: " if where else ""
    check_geometry(sample, rig, at)
    if rig.spring_constant is None:
        raise InputError(
            f"{at}curvature validation needs the sensor's spring constant",
            hint="set spring_constant_N_per_m in [rig] (one segment)",
        )
    r0s, source = initial_resistances(rig, data, provenance, at)
    options = {
        "spring_constant": float(rig.spring_constant),
        "initial_resistances": r0s,
        "initial_resistance": float(np.mean(r0s)),
    }
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


def protocol(
    rig: Rig,
    rng: np.random.Generator,
    *,
    cable_max_m: float = CABLE_MAX_M,
    cable_step_m: float = CABLE_STEP_M,
    pose_s: float | None = None,
) -> pd.DataFrame:
    """The exact cable program of one run (deterministic; ``rig`` and ``rng`` are unused).

    Without options it is the default program: 0 to :data:`CABLE_MAX_M` in
    :data:`CABLE_STEP_M` steps. A designed protocol (:func:`protocol_runs`) sets the options.

    Only positive pulls: the robot has one cable, on one side of the neutral axis, and a
    cable cannot push. A negative pull would not bend the robot the other way, and the
    sensor would be compressed, where the chapter-3 inversion has two roots or none
    (:mod:`tcamlab.models.sensing`) and the cable sharing of (4.1)
    (:func:`tcamlab.models.curvature.cable_lengths`) is not established; the model is not
    valid symmetrically, so no design offers both directions.

    Parameters
    ----------
    cable_max_m : float
        Largest cable pull [m], a whole number of steps.
    cable_step_m : float
        Cable pull step [m].
    pose_s : float, optional
        Time per pose (settle and photograph) [s]: when given, a ``time`` column [s] is
        added (a designed run's rig time); None keeps the untimed program.

    Returns
    -------
    pandas.DataFrame
        ``cable`` [m]: 0 to ``cable_max_m`` in ``cable_step_m`` steps; ``time`` [s] with ``pose_s``.
    """
    n = int(round(cable_max_m / cable_step_m)) + 1
    out = pd.DataFrame({"cable": np.arange(n) * cable_step_m})
    if pose_s is not None:
        out["time"] = np.arange(n) * float(pose_s)
    return out


PROTOCOL_KEYS = ("kind", "cable_mm", "cable_step_mm", "runs", "channels")
"""Keys of a curvature ``[protocol]`` table (docs/design.md)."""

KIND_COLUMNS = ("cable_mm", "r1_ohm", "r2_ohm", "kappa1_per_mm", "kappa2_per_mm")
"""Columns a camera curvature run logs, every one required (a ``[protocol]``'s ``channels``)."""

POSE_S = 60.0
"""Rig time per pose of a designed run [s]: the actuator steps, the silicone settles and
the camera photographs the robot."""

CABLE_LIMIT_MARGIN = 0.8
"""A design's largest cable pull stays below this share of :func:`cable_limit` [-]."""


def cable_limit(sample: Sample, rig: Rig) -> float:
    """Largest cable pull the model admits at the stated values [m].

    Under the virtual rig's bending (module docstring) segment i's sensor stretches by
    w_i c, w_i = r_i L_i / sum_j r_j L_j (r the curvature ratio). The pull must keep every
    segment's elongation inside its sensor's chapter-3 map
    (:func:`tcamlab.kinds.sensing.elongation_limit` of the sensor cut to L_i) and its cable
    length C_i = L_i - w_i c of (4.1) positive.
    """
    from tcamlab.kinds.sensing import elongation_limit

    lengths = np.asarray(rig.segment_lengths, float)
    ratio = np.ones(lengths.size)
    ratio[0] = TIP_TO_BASE_CURVATURE
    share = ratio * lengths / float(np.sum(ratio * lengths))
    limits = []
    for length, w in zip(lengths, share):
        part = length / sample.coil_length
        seg = replace(
            sample, fiber_length=sample.fiber_length * part, coil_length=length, twists=sample.twists * part
        )
        limits.append(min(elongation_limit(seg, rig), length) / w)
    return float(min(limits))


def protocol_runs(table: dict, rig: Rig) -> list[dict]:
    """Each run's :func:`protocol` options from a ``[protocol]`` table (docs/design.md): the
    largest pull ``cable_mm`` in ``cable_step_mm`` steps (mm converted to m here), every run
    timed at :data:`POSE_S` per pose. Unknown keys and bad values raise ConfigError naming the key."""
    unknown = sorted(set(table) - set(PROTOCOL_KEYS))
    if unknown:
        raise ConfigError(
            f"[protocol]: unknown key {unknown[0]!r}", "allowed keys: " + ", ".join(PROTOCOL_KEYS)
        )
    values = {}
    for key, default, hint in (
        ("cable_mm", CABLE_MAX_M * 1e3, "e.g. cable_mm = 10.0"),
        ("cable_step_mm", CABLE_STEP_M * 1e3, "e.g. cable_step_mm = 1.0"),
    ):
        v = table.get(key, default)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 < v < np.inf:
            raise ConfigError(f"[protocol]: {key} must be a positive number, got {v!r}", hint)
        values[key] = float(v) * 1e-3
    top, step = values["cable_mm"], values["cable_step_mm"]
    pv.levels(
        top / step,
        f"cable_mm ({top * 1e3:g}) over cable_step_mm ({step * 1e3:g})",
        "e.g. cable_mm = 10.0 with cable_step_mm = 0.5",
    )
    pv.channels(table, KIND_COLUMNS, KIND_COLUMNS, list(KIND_COLUMNS), "the camera rig")
    n = pv.runs(table, 1)
    return [{"cable_max_m": top, "cable_step_m": step, "pose_s": POSE_S} for _ in range(n)]


def design_menu(sample: Sample, rig: Rig) -> list[tuple[str, dict]]:
    """Candidate protocols of a camera curvature test [(name, ``[protocol]`` table)].

    The default program (0-10 mm in 1 mm steps) repeated, finer bending levels (0.5 mm
    steps) and a larger range (1.5 x, kept below :data:`CABLE_LIMIT_MARGIN` of
    :func:`cable_limit` at the stated values). Two runs each. Both directions are not
    offered: the model is not valid for negative pulls (:func:`protocol`).
    """
    step_mm = CABLE_STEP_M * 1e3
    top = CABLE_LIMIT_MARGIN * cable_limit(sample, rig) * 1e3
    larger = round(float(step_mm * np.floor(min(1.5 * CABLE_MAX_M * 1e3, top) / step_mm)), 3)
    base = {
        "kind": "curvature",
        "cable_mm": round(CABLE_MAX_M * 1e3, 3),
        "cable_step_mm": step_mm,
        "runs": 2,
        "channels": list(KIND_COLUMNS),
    }
    menu = [("repeat (same protocol)", base)]
    menu.append(("finer levels 0.5 mm", {**base, "cable_step_mm": 0.5}))
    if larger > base["cable_mm"]:
        menu.append((f"larger range 1.5x, to {larger:g} mm", {**base, "cable_mm": larger}))
    return menu


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
    required_columns=KIND_COLUMNS,
    optional_columns=("time_s",),
    min_rows=2,
    inputs=("cable", "r1", "r2"),
    # no time column: the rows at rest are those at the smallest pull, wherever they are
    rest_rule=rest_rows,
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
    program_options=("cable_max_m", "cable_step_m", "pose_s"),
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
