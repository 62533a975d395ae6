"""Experiment files: loading, validation and writing.

An experiment file ``experiments/NAME.toml`` describes one experiment: its
kind, the CSV runs (paths relative to the TOML file), the sample, the rig,
how the CSV headers map to canonical columns and the acceptance thresholds::

    kind = "dynamic"
    title = "Voltage step, 50 g"
    runs = ["../raw/step_50g_1.csv", "../raw/step_50g_2.csv"]
    notes = "optional"

    [synthetic]            # optional: marks simulated data
    generator = "tcamlab.simulate"
    seed = 42
    command = "tcamlab simulate dynamic ..."

    [sample]
    preset = "thesis-tca"  # optional; other keys override the preset
    coil_length_mm = 21.0

    [rig]
    load_g = 50
    [rig.uncertainty]      # standard deviations, same units
    damping_N_s_per_m = 0.12

    [columns]
    time_s = { from = "reltime", unit = "ms" }

    [thresholds]
    rmse_mm = 0.5

    [calibration]          # optional: written by tcamlab calibrate
    parameters = ["rig.thermal_mass_J_per_K", "rig.damping_N_s_per_m"]
    coordinates = ["log", "log"]   # log: sd relative [-]; linear: sd in the key's unit
    sd = [0.004, 0.03]             # Laplace sds
    correlation = [[1.0, 0.2], [0.2, 1.0]]
    sd_below = [0.004, 0.035]      # optional, together: profile 95 % interval / 1.96
    sd_above = [0.004, 0.028]

The file is validated with pydantic models (unknown keys are errors) and
every problem is reported as a one-line :class:`tcamlab.errors.ConfigError`
naming the file and the key. Lab units in key names are converted to SI with
the factors of :data:`tcamlab.params.SAMPLE_KEYS` and
:data:`tcamlab.params.RIG_KEYS`.
"""

from __future__ import annotations

import math
import os
import re
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, create_model

from tcamlab import io as tio
from tcamlab.errors import ConfigError
from tcamlab.params import PRESETS, RIG_KEYS, SAMPLE_KEYS, Rig, Sample, get_preset
from tcamlab.text import did_you_mean

__all__ = [
    "KINDS",
    "Experiment",
    "CalibratedJoint",
    "load_experiment",
    "write_experiment",
    "merge_run_columns",
    "dumps_toml",
]

KINDS = tio.KINDS
"""Experiment kinds."""

EXPERIMENT_FILE = "experiment file"
"""Provenance text of a value set in the experiment file."""

RIG_DEFAULT = "tcamlab default (tcamlab.params.Rig; not set by the preset or the experiment file)"
"""Provenance text of a rig value that neither the preset nor the file sets."""

_LIST_KEYS = {"segment_lengths_mm"}

MAX_EXPERIMENT_BYTES = 1024**2
"""Largest experiment file :func:`load_experiment` reads [bytes] (1 MiB)."""

# --- pydantic models ----------------------------------------------------------

_STRICT = ConfigDict(extra="forbid", strict=True)


class _Synthetic(BaseModel):
    model_config = _STRICT
    generator: str
    seed: int
    command: str | None = None


def _sample_field(key: str):
    if key == "thread_plies":
        return (int | None, None)
    return (float | None, None)


_SampleUncertainty = create_model(
    "_SampleUncertainty", __config__=_STRICT, **{key: (float | None, None) for key in SAMPLE_KEYS}
)
RUN_TO_RUN_FIELDS = ("twists", "coil_length", "coil_diameter", "fiber_diameter", "fiber_length")
"""Sample fields a run may depart from the sample by (``[sample.run_to_run]``, relative sds)."""
MAX_RUN_TO_RUN = 0.1
"""Largest run-to-run relative sd accepted: beyond 10 % the runs are not one sample."""
_RunToRun = create_model(
    "_RunToRun", __config__=_STRICT, **{key: (float | None, None) for key in RUN_TO_RUN_FIELDS}
)
_SampleTable = create_model(
    "_SampleTable",
    __config__=_STRICT,
    uncertainty=(_SampleUncertainty | None, None),
    run_to_run=(_RunToRun | None, None),
    preset=(Literal[tuple(PRESETS)] | None, None),  # type: ignore[valid-type]
    **{key: _sample_field(key) for key in SAMPLE_KEYS},
)


def _rig_fields() -> dict[str, Any]:
    return {
        key: ((list[float] | None, None) if key in _LIST_KEYS else (float | None, None)) for key in RIG_KEYS
    }


_RigUncertainty = create_model("_RigUncertainty", __config__=_STRICT, **_rig_fields())
_RigTable = create_model(
    "_RigTable",
    __config__=_STRICT,
    uncertainty=(_RigUncertainty | None, None),
    **_rig_fields(),
)


class _ColumnTable(BaseModel):
    """One inline table of ``[columns]``."""

    model_config = ConfigDict(extra="forbid", strict=True, populate_by_name=True)
    from_: str | int = Field(alias="from")
    unit: str | None = None
    scale: float | None = None
    offset: float | None = None


class _CalibrationTable(BaseModel):
    """``[calibration]``: the joint posterior of calibrated parameters (checked further in
    :func:`_calibration`)."""

    model_config = _STRICT
    parameters: list[str] = Field(min_length=1)
    coordinates: list[Literal["log", "linear"]]
    sd: list[float]
    correlation: list[list[float]]
    sd_below: list[float] | None = None
    sd_above: list[float] | None = None


class _ValidationTable(BaseModel):
    """``[validation]``: how ``validate`` takes each run's nuisance zero (checked further in
    :func:`_zero_rule`)."""

    model_config = _STRICT
    zero: str = "rest"


class _JoinTable(BaseModel):
    """A second instrument's file joined to a run on time (its own clock, ``offset_s`` added)."""

    model_config = _STRICT
    file: str
    columns: dict[str, Any] = Field(default_factory=dict)
    offset_s: float = 0.0


class _RunTable(BaseModel):
    """A run given as a table: its file, its own ``[columns]`` overrides (a per-run scale) and
    a second instrument's file to join on time."""

    model_config = _STRICT
    file: str
    columns: dict[str, Any] = Field(default_factory=dict)
    join: _JoinTable | None = None


class _ExperimentFile(BaseModel):
    model_config = _STRICT
    kind: Literal[KINDS]  # type: ignore[valid-type]
    title: str
    runs: list[str | _RunTable] = Field(min_length=1)
    notes: str | None = None
    synthetic: _Synthetic | None = None
    sample: _SampleTable | None = None  # type: ignore[valid-type]
    rig: _RigTable | None = None  # type: ignore[valid-type]
    columns: dict[str, Any] = Field(default_factory=dict)
    thresholds: dict[str, Any] = Field(default_factory=dict)
    calibration: _CalibrationTable | None = None
    validation: _ValidationTable | None = None
    protocol: dict[str, Any] | None = None  # a designed protocol (tcamlab design): read by the rig


class _TemplateFile(_ExperimentFile):
    """An experiment file used as a simulation template: ``runs`` may be empty or absent."""

    runs: list[str | _RunTable] = Field(default_factory=list)


def _model_keys(model: type[BaseModel]) -> list[str]:
    return [f.alias or name for name, f in model.model_fields.items()]


_ALLOWED_KEYS: dict[tuple[str, ...], list[str]] = {
    (): _model_keys(_ExperimentFile),
    ("synthetic",): _model_keys(_Synthetic),
    ("sample",): _model_keys(_SampleTable),
    ("sample", "uncertainty"): _model_keys(_SampleUncertainty),
    ("sample", "run_to_run"): _model_keys(_RunToRun),
    ("rig",): _model_keys(_RigTable),
    ("rig", "uncertainty"): _model_keys(_RigUncertainty),
    ("calibration",): _model_keys(_CalibrationTable),
    ("validation",): _model_keys(_ValidationTable),
    ("runs",): _model_keys(_RunTable),
    ("runs", "join"): _model_keys(_JoinTable),
}

_EXPECTED = {
    "float_type": "a number",
    "float_parsing": "a number",
    "finite_number": "a finite number",
    "int_type": "an integer",
    "int_parsing": "an integer",
    "int_from_float": "an integer",
    "string_type": "a string",
    "list_type": "a list",
    "dict_type": "a table",
    "model_type": "a table",
    "model_attributes_type": "a table",
    "bool_type": "true or false",
}

# --- the result ---------------------------------------------------------------


@dataclass(frozen=True)
class CalibratedJoint:
    """The ``[calibration]`` table: the joint posterior of the calibrated parameters.

    The centre is the calibrated value in ``[rig]`` / ``[sample]``; the spread is
    Gaussian in the coordinates the calibration fits (:mod:`tcamlab.calibration`):
    ``log(value)`` for a positive parameter, the value itself otherwise.

    Attributes
    ----------
    keys : tuple of str
        As written, ``"rig.thermal_mass_J_per_K"``.
    fields : tuple of (str, str)
        ``("rig" or "sample", SI field)`` of each key.
    log : tuple of bool
        Whether each is fitted as its logarithm.
    sd : tuple of float
        Posterior sd in the fitted coordinate (Laplace): relative [-] for log, SI otherwise.
    correlation : tuple of tuple of float
        Posterior correlation matrix in the fitted coordinates [-].
    sd_below, sd_above : tuple of float or None
        Sds below and above the value from the profile-likelihood 95 % interval
        (its distance from the value / 1.96), same units as ``sd``; None when not written.
    """

    keys: tuple[str, ...]
    fields: tuple[tuple[str, str], ...]
    log: tuple[bool, ...]
    sd: tuple[float, ...]
    correlation: tuple[tuple[float, ...], ...]
    sd_below: tuple[float, ...] | None = None
    sd_above: tuple[float, ...] | None = None

    def covariance(self) -> np.ndarray:
        """Posterior covariance in the fitted coordinates (log: [-]; linear: SI squared)."""
        sd = np.asarray(self.sd, float)
        return np.asarray(self.correlation, float) * np.outer(sd, sd)


@dataclass(frozen=True)
class Experiment:
    """A loaded and validated experiment file.

    Attributes
    ----------
    path : pathlib.Path
        The TOML file, resolved.
    name : str
        File stem (``experiments/step_50g.toml`` -> ``"step_50g"``).
    kind : str
        ``"static"``, ``"dynamic"``, ``"sensing"`` or ``"curvature"``.
    title : str
        Human-readable title.
    notes : str or None
        Free text.
    runs : tuple of pathlib.Path
        CSV files, absolute and resolved; all exist.
    sample : tcamlab.params.Sample
        The sample in SI (for kind curvature: the embedded sensor).
    rig : tcamlab.params.Rig
        Rig parameters in SI, with ``uncertainty`` (standard deviations, SI).
    columns : dict
        The ``[columns]`` table as written (canonical name -> header or
        inline table), validated for this kind; pass it to
        :func:`tcamlab.io.read_run`.
    thresholds : dict of str to float
        Metric name -> acceptance limit.
    synthetic : dict or None
        ``{"generator", "seed", "command"}`` when the runs are simulated.
    provenance : dict of str to str
        SI field name -> where its value comes from (the preset's provenance
        text or ``"experiment file"``); uncertainties as ``"sd(field)"``.
    raw : dict
        The parsed TOML document.
    sample_uncertainty : dict of str to float
        ``[sample.uncertainty]``: standard deviations of sample fields [SI], by SI field name.
    calibration : CalibratedJoint or None
        ``[calibration]``: the joint posterior of a calibrated file (``tcamlab calibrate``).
    run_columns : tuple of dict
        Each run's ``[columns]``: the table merged with the run's own overrides
        (``runs = [{ file = "...", columns = { displacement_mm = { scale = 0.35 } } }]``);
        empty when no run has any.
    run_joins : tuple of dict or None
        Each run's second instrument file (``{"file", "columns", "offset_s", "shown"}`` for
        :func:`tcamlab.io.read_run`'s ``join``) or None; empty when no run has one.
    run_to_run : dict of str to float or None
        ``[sample.run_to_run]``: the lab's run-to-run reproducibility, relative sds [-] of
        sample fields (re-mounting a sensor changes its twists and coil length a little);
        calibration treats each run's departure as a random effect. None: the kind's default
        (:attr:`tcamlab.kinds.Kind.run_reproducibility`).
    zero_rule : str
        ``[validation] zero``: ``"rest"`` (default; each run's zero from its rows at rest,
        else as logged) or ``"whole-run"`` (:data:`tcamlab.metrics.ZERO_RULES`).
    """

    path: Path
    name: str
    kind: str
    title: str
    notes: str | None
    runs: tuple[Path, ...]
    sample: Sample
    rig: Rig
    columns: dict = field(default_factory=dict)
    thresholds: dict[str, float] = field(default_factory=dict)
    synthetic: dict | None = None
    provenance: dict[str, str] = field(default_factory=dict)
    raw: dict = field(default_factory=dict)
    sample_uncertainty: dict[str, float] = field(default_factory=dict)
    calibration: CalibratedJoint | None = None
    run_columns: tuple[dict, ...] = ()
    run_joins: tuple[dict | None, ...] = ()
    run_to_run: dict[str, float] | None = None
    zero_rule: str = "rest"

    @property
    def preset(self) -> str | None:
        """Name of the ``[sample]`` preset, or None."""
        return (self.raw.get("sample") or {}).get("preset")

    def read_runs(
        self, *, drop_na: bool = False, max_bytes: int = tio.DEFAULT_MAX_BYTES
    ) -> list[tio.RunData]:
        """Read every run with this experiment's kind and ``[columns]``.

        Parameters
        ----------
        drop_na : bool
            Drop rows with blank cells instead of raising.
        max_bytes : int
            Largest file to read [bytes].

        Returns
        -------
        list of tcamlab.io.RunData
        """
        columns = self.run_columns or (self.columns,) * len(self.runs)
        joins = self.run_joins or (None,) * len(self.runs)
        return [
            tio.read_run(
                p, self.kind, c, drop_na=drop_na, max_bytes=max_bytes, shown=_display_path(p), join=j
            )
            for p, c, j in zip(self.runs, columns, joins)
        ]


# --- loading --------------------------------------------------------------------


def _loc_text(loc: tuple) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += ("." if out else "") + str(part)
    return out


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _translate(err: ValidationError, shown: str, prefix: tuple = ()) -> ConfigError:
    """One-line :class:`ConfigError` naming every problem pydantic found, so all are fixed at once."""
    # An unknown key usually explains a "missing" one (a typo): report it first.
    errors = sorted(_one_branch(err.errors(include_url=False)), key=lambda e: e["type"] != "extra_forbidden")
    described = [_describe(e, shown, prefix) for e in errors]
    if len(described) == 1:
        return described[0]
    head = f"{shown}: "
    parts = [d.message[len(head) :] if d.message.startswith(head) else d.message for d in described]
    hints = [d.hint for d in described if d.hint]
    return ConfigError(
        f"{shown}: {len(parts)} problems: " + "; ".join(f"({i + 1}) {m}" for i, m in enumerate(parts)),
        " | ".join(dict.fromkeys(hints)) or None,
    )


def _one_branch(errors: list) -> list:
    """A run is a file name or a table: keep the errors of the form the user wrote (a table's
    for a table, the string's otherwise), without pydantic's branch names in the location."""
    out = []
    for e in errors:
        loc = tuple(e["loc"])
        if loc[:1] == ("runs",) and len(loc) > 2 and loc[2] in ("str", "_RunTable"):
            wrote_table = isinstance(e.get("input"), Mapping) if len(loc) == 3 else True
            if (loc[2] == "str") == wrote_table:
                continue
            e = {**e, "loc": loc[:2] + loc[3:]}
        out.append(e)
    return out or errors


def _describe(e: Mapping[str, Any], shown: str, prefix: tuple = (), more: str = "") -> ConfigError:
    loc = tuple(prefix) + tuple(e["loc"])
    key = _loc_text(loc)
    kind = e["type"]
    if kind == "extra_forbidden":
        parent = tuple(p for p in loc[:-1] if isinstance(p, str))
        allowed = _ALLOWED_KEYS.get(parent)
        if allowed is None and parent[:1] == ("columns",):
            allowed = ["from", "unit", "scale", "offset"]
        allowed = allowed or []
        table = f"[{'.'.join(parent)}]" if parent else "the top level"
        return ConfigError(
            f"{shown}: unknown key {key!r} in {table}" + did_you_mean(str(loc[-1]), allowed) + more,
            "allowed keys: " + ", ".join(allowed) if allowed else None,
        )
    if kind == "missing":
        return ConfigError(f"{shown}: missing required key {key!r}{more}", _hint_for(loc))
    if kind == "literal_error":
        expected = e.get("ctx", {}).get("expected", "")
        return ConfigError(
            f"{shown}: {key}: expected one of {expected}, got {_short(e['input'])}"
            + (did_you_mean(e["input"], _literal_choices(loc)) if isinstance(e["input"], str) else "")
            + more
        )
    if kind == "too_short":
        return ConfigError(f"{shown}: {key}: needs at least one entry{more}", _hint_for(loc))
    if kind in _EXPECTED:
        numeric = kind.startswith(("float", "int"))
        hint = (
            "numbers are written without quotes in TOML" if numeric and isinstance(e["input"], str) else None
        )
        return ConfigError(
            f"{shown}: {key}: expected {_EXPECTED[kind]}, got {_short(e['input'])}{more}",
            hint or (_hint_for(loc) if loc[:1] == ("runs",) else None),
        )
    return ConfigError(f"{shown}: {key}: {e['msg']}{more}")


def _literal_choices(loc: tuple) -> list[str]:
    if loc and loc[0] == "kind":
        return list(KINDS)
    if loc[:2] == ("sample", "preset"):
        return list(PRESETS)
    return []


def _hint_for(loc: tuple) -> str | None:
    hints = {
        "kind": f'kind = "{KINDS[0]}" (or {", ".join(KINDS[1:])})',
        "title": 'title = "what this experiment is"',
        "runs": 'runs = ["../raw/run1.csv"] (paths relative to the experiment file), or a run as a '
        'table: { file = "../raw/run2.csv", columns = { displacement_mm = { scale = -0.3 } } }',
    }
    return hints.get(loc[0]) if loc else None


def _is_dir(p: Path) -> bool:
    try:
        return p.is_dir()
    except OSError:
        return False


def _display_path(p: Path) -> str:
    """``p`` relative to the working directory when it lies below it, else as it is.

    Error messages end up in ``index.html``; this keeps the absolute location
    of the user's working directory out of them.
    """
    # "edge/../raw/run.csv" is below the working directory too
    p = Path(os.path.normpath(p))
    try:
        return str(p.relative_to(Path.cwd().resolve()))
    except (ValueError, OSError):
        return str(p)


def _finite(shown: str, key: str, value: Any) -> float:
    if not math.isfinite(value):
        raise ConfigError(f"{shown}: {key}: expected a finite number, got {value!r}")
    return float(value)


def load_experiment(
    path: str | os.PathLike, expected_kind: str | None = None, *, require_runs: bool = True
) -> Experiment:
    """Load, validate and convert an experiment file.

    Parameters
    ----------
    path : path-like
        The TOML file.
    expected_kind : str, optional
        Kind the caller handles; a file of another kind raises.
    require_runs : bool
        False for a simulation template: ``runs`` may then be absent or
        empty and listed run files need not exist (they are resolved but
        not checked).

    Returns
    -------
    Experiment
        Sample and rig in SI, runs resolved and checked to exist.

    Raises
    ------
    ConfigError
        Missing file, TOML syntax error (with line and column), unknown or
        missing key, wrong type, missing run file, impossible sample or rig,
        or a kind other than ``expected_kind``.
    """
    p, shown = Path(path), str(path)
    raw = _read_toml(p, shown)
    _refuse_placeholders(raw, shown)
    try:
        doc = (_ExperimentFile if require_runs else _TemplateFile).model_validate(raw)
    except ValidationError as exc:
        raise _translate(exc, shown) from None
    kind = doc.kind
    if expected_kind is not None and expected_kind != kind:
        raise ConfigError(
            f"{shown}: this is a {kind!r} experiment, not {expected_kind!r}",
            f"run it with the '{kind}' subcommand",
        )
    entries = _expand_globs(doc.runs, p, shown) if require_runs else list(doc.runs)
    runs = _resolve_runs([r if isinstance(r, str) else r.file for r in entries], p, shown, require_runs)
    columns, thresholds = _columns(doc.columns, kind, shown), _thresholds(doc, shown)
    run_columns = _run_columns(entries, columns, kind, shown)
    run_joins = _run_joins(entries, p, kind, shown, require_runs)
    sample, sample_prov = _build_sample(doc, shown)
    sample_unc = _sample_uncertainty(doc, shown)
    rig, rig_prov = _build_rig(doc, shown)
    return Experiment(
        path=p.resolve(),
        name=p.stem,
        kind=kind,
        title=doc.title,
        notes=doc.notes,
        runs=tuple(runs),
        sample=sample,
        rig=rig,
        columns=columns,
        thresholds=thresholds,
        synthetic=doc.synthetic.model_dump() if doc.synthetic else None,
        provenance={**sample_prov, **rig_prov, **{f"sd({k})": EXPERIMENT_FILE for k in sample_unc}},
        raw=raw,
        sample_uncertainty=sample_unc,
        calibration=_calibration(doc.calibration, sample, rig, shown),
        run_columns=run_columns,
        run_joins=run_joins,
        run_to_run=_run_to_run(doc, shown),
        zero_rule=_zero_rule(doc, shown),
    )


def _refuse_placeholders(raw: dict, shown: str) -> None:
    """Refuse a starter file (``tcamlab init``) whose placeholders are not all filled in, naming every one."""
    from tcamlab.starter import PLACEHOLDER, placeholders

    # only where init writes them: a title such as "Fill in the oven log" is not one
    left = placeholders({k: raw[k] for k in ("runs", "columns", "sample", "rig") if k in raw})
    if left:
        raise ConfigError(
            f"{shown}: {len(left)} value{'s' if len(left) > 1 else ''} still to fill in "
            f'(left as "{PLACEHOLDER} ..." by tcamlab init): ' + ", ".join(left),
            "replace each with the measured number (or the header / column number); "
            "the comment above each key says what it is and how to measure it",
        )


def _read_bytes(p: Path, shown: str) -> bytes:
    """The file's bytes, refusing a missing, special or oversized file."""
    try:
        is_file, exists = p.is_file(), p.exists()
    except (OSError, ValueError) as exc:
        raise ConfigError(
            f"{shown}: cannot be used as a file name ({getattr(exc, 'strerror', None) or exc})"
        ) from None
    if not is_file:
        raise ConfigError(
            f"{shown}: experiment file not found" if not exists else f"{shown}: not a file",
            "experiment files live in experiments/NAME.toml",
        )
    try:
        size = p.stat().st_size
        if size > MAX_EXPERIMENT_BYTES:
            raise ConfigError(
                f"{shown}: experiment file is {size} bytes, larger than the limit of "
                f"{MAX_EXPERIMENT_BYTES} bytes",
                "an experiment file is a few lines of TOML; check that the right file is named",
            )
        return p.read_bytes()
    except OSError as exc:
        raise ConfigError(
            f"{shown}: cannot read the file ({exc.strerror or exc})", "check that it exists and is readable"
        ) from None


def _read_toml(p: Path, shown: str) -> dict:
    """The parsed TOML document, with a one-line error for anything that is not UTF-8 TOML."""
    data = _read_bytes(p, shown)
    if p.suffix.lower() in (".csv", ".tsv", ".dat", ".txt"):
        raise ConfigError(
            f"{shown}: is a CSV log, not an experiment file",
            "an experiment file (TOML) lists the CSV runs with the sample and rig; write one "
            "from this log with: tcamlab init KIND --csv " + shown,
        )
    # Editors on Windows often save UTF-8 with a byte-order mark, which
    # tomllib refuses as an "invalid statement" at line 1: accept it.
    if data.startswith(b"\xef\xbb\xbf"):
        data = data[3:]
    try:
        return tomllib.loads(data.decode("utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(
            f"{shown}: TOML syntax error: {' '.join(str(exc).split())}",
            "see https://toml.io; strings need quotes, tables are [name]",
        ) from None
    except UnicodeDecodeError as exc:
        raise ConfigError(
            f"{shown}: not UTF-8 text ({exc.reason} at byte {exc.start})", "save it as UTF-8"
        ) from None
    except RecursionError:
        raise ConfigError(
            f"{shown}: TOML nested too deeply",
            "arrays and tables nest only a few levels in an experiment file",
        ) from None


def _expand_globs(entries: list, p: Path, shown: str) -> list:
    """Run names with ``*``, ``?`` or ``[`` expanded (relative to the experiment file, sorted)."""
    base = p.resolve().parent
    out: list = []
    for i, run in enumerate(entries):
        if not isinstance(run, str) or not any(ch in run for ch in "*?[") or Path(run).is_absolute():
            out.append(run)
            continue
        try:
            found = sorted(q for q in base.glob(run) if q.is_file())
        except (ValueError, OSError) as exc:
            raise ConfigError(f"{shown}: runs[{i}]: {_short(run)} is not a usable pattern ({exc})") from None
        if not found:
            raise ConfigError(
                f"{shown}: runs[{i}]: the pattern {_short(run)} matches no file (looked in {_display_path(base)})",
                'patterns are relative to the experiment file, e.g. runs = ["../raw/pull_*.csv"]',
            )
        out += [os.path.relpath(q, base) for q in found]
    return out


def _resolve_runs(run_list, p: Path, shown: str, require_runs: bool) -> list[Path]:
    """Run paths resolved against the experiment file's folder, checked to be files."""
    base = p.resolve().parent
    runs = []
    for i, run in enumerate(run_list):
        shown_run = _short(run)
        if not run.strip() or "\x00" in run:
            raise ConfigError(
                f"{shown}: runs[{i}]: {shown_run} is not a file name",
                'e.g. runs = ["../raw/run1.csv"] (relative to the experiment file)',
            )
        try:
            rp = Path(run)
            rp = (rp if rp.is_absolute() else base / rp).resolve()
            is_file = rp.is_file()
        except (OSError, ValueError) as exc:
            raise ConfigError(
                f"{shown}: runs[{i}]: {shown_run} cannot be used as a file name "
                f"({getattr(exc, 'strerror', None) or exc})",
                "run paths are relative to the experiment file",
            ) from None
        if require_runs and not is_file:
            what = "is a folder, not a file" if _is_dir(rp) else "not found"
            raise ConfigError(
                f"{shown}: runs[{i}]: run file {shown_run} {what} (looked for {_display_path(rp)})",
                "run paths are relative to the experiment file",
            )
        if rp in runs:  # the same log twice would count as two runs in every fold and interval
            raise ConfigError(
                f"{shown}: runs[{i}]: {shown_run} is runs[{runs.index(rp)}] again",
                "list each run file once",
            )
        runs.append(rp)
    return runs


def _columns(table: Mapping[str, Any], kind: str, shown: str, where: str = "columns") -> dict[str, Any]:
    """A [columns] table: its layout keys (``header_row``, ``units_row``) and each entry checked
    against the kind's canonical columns."""
    fmt, entries = tio.file_format(table, where=f"{shown}: {where}", error=ConfigError)
    columns: dict[str, Any] = {k: table[k] for k in tio.FORMAT_KEYS if k in table}
    problems: list[ConfigError] = []
    for canon, spec in entries.items():
        try:
            if isinstance(spec, Mapping):
                try:
                    _ColumnTable.model_validate(spec)
                except ValidationError as exc:
                    raise _translate(exc, shown, prefix=tuple(where.split(".")) + (canon,)) from None
            tio.column_spec(kind, canon, spec, where=f"{shown}: {where}", error=ConfigError)
        except ConfigError as exc:
            problems.append(exc)
        columns[canon] = dict(spec) if isinstance(spec, Mapping) else spec
    if len(problems) == 1:
        raise problems[0]
    if problems:  # every bad entry at once, not one per run of the command
        head = f"{shown}: "
        parts = [e.message[len(head) :] if e.message.startswith(head) else e.message for e in problems]
        raise ConfigError(
            f"{shown}: {len(parts)} problems in [{where}]: "
            + "; ".join(f"({i + 1}) {m}" for i, m in enumerate(parts)),
            " | ".join(dict.fromkeys(e.hint for e in problems if e.hint)) or None,
        )
    return columns


def _run_columns(entries: list, columns: dict[str, Any], kind: str, shown: str) -> tuple[dict, ...]:
    """Each run's [columns]: the table with the run's own overrides merged in, key by key."""
    if all(isinstance(r, str) or not r.columns for r in entries):
        return ()
    out = []
    for i, run in enumerate(entries):
        merged = merge_run_columns(columns, {} if isinstance(run, str) else run.columns)
        out.append(_columns(merged, kind, shown, where=f"runs[{i}].columns"))
    return tuple(out)


def merge_run_columns(table: Mapping[str, Any], own: Mapping[str, Any]) -> dict[str, Any]:
    """A run's ``[columns]``: the experiment's ``table`` with the run's ``own`` entries merged in
    key by key (an entry's ``from`` kept where the run only changes its unit or scale)."""
    merged = dict(table)
    for canon, spec in own.items():
        base = merged.get(canon)
        if isinstance(spec, Mapping) and canon not in tio.FORMAT_KEYS:
            base = {"from": base} if isinstance(base, str) else dict(base or {})
            merged[canon] = base | dict(spec)
        else:
            merged[canon] = spec
    return merged


def _run_joins(entries: list, p: Path, kind: str, shown: str, require_runs: bool) -> tuple:
    """Each run's join table resolved: the second file (relative to the experiment file), its
    checked [columns] (``time_s`` required) and ``offset_s``; () when no run has one."""
    if all(isinstance(r, str) or r.join is None for r in entries):
        return ()
    out: list[dict | None] = []
    for i, run in enumerate(entries):
        if isinstance(run, str) or run.join is None:
            out.append(None)
            continue
        where = f"runs[{i}].join"
        (jp,) = _resolve_runs([run.join.file], p, f"{shown}: {where}", require_runs)
        cols = _columns(run.join.columns, kind, shown, where=f"{where}.columns")
        if not [c for c in cols if c not in tio.FORMAT_KEYS and c != "time_s"]:
            raise ConfigError(
                f"{shown}: {where}.columns: names no column to take from {run.join.file}",
                'e.g. columns = { time_s = "t", temperature_C = "T (C)" }',
            )
        offset = _finite(shown, f"{where}.offset_s", run.join.offset_s)
        out.append({"file": jp, "columns": cols, "offset_s": offset, "shown": _display_path(jp)})
    return tuple(out)


def _thresholds(doc: _ExperimentFile, shown: str) -> dict[str, float]:
    """The [thresholds] table as finite numbers."""
    thresholds: dict[str, float] = {}
    for name, value in doc.thresholds.items():
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f"{shown}: thresholds.{name}: expected a number, got {_short(value)}")
        v = thresholds[name] = _finite(shown, f"thresholds.{name}", value)
        # a limit no run can meet would fail every validation whatever the model does
        if name.startswith("r2_min") and v > 1:
            raise ConfigError(
                f"{shown}: thresholds.{name} = {value!r}: R² is at most 1", f"e.g. {name} = 0.9"
            )
        if not name.startswith("r2") and v < 0:
            raise ConfigError(
                f"{shown}: thresholds.{name} = {value!r}: a limit on an error's size is not negative",
                f"e.g. {name} = {abs(v):g}",
            )
    return thresholds


def _build_sample(doc: _ExperimentFile, shown: str) -> tuple[Sample, dict[str, str]]:
    table = doc.sample.model_dump(exclude_none=True) if doc.sample else {}
    table.pop("uncertainty", None)
    table.pop("run_to_run", None)
    preset_name = table.pop("preset", None)
    overrides: dict[str, Any] = {}
    for key, value in table.items():
        si_name, factor = SAMPLE_KEYS[key]
        v = _finite(shown, f"sample.{key}", value)
        overrides[si_name] = int(value) if key == "thread_plies" else v * factor
    provenance = {name: EXPERIMENT_FILE for name in overrides}
    try:
        if preset_name is None:
            missing = [k for k, (si, _) in SAMPLE_KEYS.items() if si not in overrides]
            if missing:
                raise ConfigError(
                    f"{shown}: [sample] has no preset, so every sample key is required; "
                    f"missing: {', '.join(missing)}",
                    'add preset = "thesis-tca" (or another of '
                    + ", ".join(sorted(PRESETS))
                    + ") to [sample], or give the missing keys",
                )
            sample = Sample(**overrides)
        else:
            preset = get_preset(preset_name)
            sample = preset.build_sample(**overrides)
            provenance = {
                k: (EXPERIMENT_FILE if k in overrides else v.provenance) for k, v in preset.sample.items()
            } | provenance
    except ConfigError as exc:
        if exc.message.startswith(shown):
            raise
        raise ConfigError(f"{shown}: {exc.message}", exc.hint) from None
    return sample, provenance


def _sample_uncertainty(doc: _ExperimentFile, shown: str) -> dict[str, float]:
    """``[sample.uncertainty]`` in SI by field name; every sd a non-negative finite number."""
    table = (
        doc.sample.uncertainty.model_dump(exclude_none=True) if doc.sample and doc.sample.uncertainty else {}
    )
    out: dict[str, float] = {}
    for key, value in table.items():
        si_name, factor = SAMPLE_KEYS[key]
        v = _finite(shown, f"sample.uncertainty.{key}", value)
        if v < 0:
            raise ConfigError(
                f"{shown}: sample.uncertainty.{key} = {value!r} must not be negative",
                "uncertainties are standard deviations",
            )
        out[si_name] = v * factor
    return out


def _zero_rule(doc: _ExperimentFile, shown: str) -> str:
    """``[validation] zero``: one of :data:`tcamlab.metrics.ZERO_RULES` (default ``"rest"``)."""
    from tcamlab.metrics import ZERO_RULES

    rule = doc.validation.zero if doc.validation else ZERO_RULES[0]
    if rule not in ZERO_RULES:
        raise ConfigError(
            f"{shown}: validation.zero = {rule!r} is not a zero rule",
            'use "rest" (zeros from the rows at rest, else as logged; the default) or "whole-run" '
            "(each model's zero fitted over the whole run: bias 0 by construction)",
        )
    return rule


def _run_to_run(doc: _ExperimentFile, shown: str) -> dict[str, float] | None:
    """``[sample.run_to_run]`` (relative sds, each in [0, MAX_RUN_TO_RUN]), or None if absent."""
    if not (doc.sample and doc.sample.run_to_run):
        return None
    out: dict[str, float] = {}
    for key, value in doc.sample.run_to_run.model_dump(exclude_none=True).items():
        v = _finite(shown, f"sample.run_to_run.{key}", value)
        if not 0.0 <= v <= MAX_RUN_TO_RUN:
            raise ConfigError(
                f"{shown}: sample.run_to_run.{key} = {value!r} is not a relative sd in [0, {MAX_RUN_TO_RUN}]",
                f"e.g. {key} = 5e-4 (0.05 % between runs); 0 treats the runs as one geometry",
            )
        out[key] = v
    return out


def _rig_values(table: Mapping[str, Any], shown: str, where: str, sd: bool) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in table.items():
        si_name, factor = RIG_KEYS[key]
        if key in _LIST_KEYS:
            values = [_finite(shown, f"{where}.{key}[{i}]", v) * factor for i, v in enumerate(value)]
            if not values:
                raise ConfigError(f"{shown}: {where}.{key}: needs at least one entry")
            if sd:
                out[si_name] = tuple(values)
                bad = [v for v in values if v < 0]
            else:
                out[si_name] = tuple(values)
                bad = [v for v in values if v <= 0]
            if bad:
                raise ConfigError(
                    f"{shown}: {where}.{key}: every entry must be "
                    + ("non-negative" if sd else "positive")
                    + f", got {list(value)!r}"
                )
            continue
        v = _finite(shown, f"{where}.{key}", value)
        out[si_name] = v * factor
    return out


def _calibration_fields(table, sample: Sample, rig: Rig, shown: str) -> list[tuple[str, str]]:
    """``(where, SI field)`` of each ``calibration.parameters`` key, checked to be known and valued."""
    out: list[tuple[str, str]] = []
    for i, key in enumerate(table.parameters):
        where, _, name = key.partition(".")
        keys = {"rig": RIG_KEYS, "sample": SAMPLE_KEYS}.get(where)
        if keys is None or name not in keys or name in _LIST_KEYS:
            known = [f"rig.{k}" for k in RIG_KEYS if k not in _LIST_KEYS] + [
                f"sample.{k}" for k in SAMPLE_KEYS
            ]
            raise ConfigError(
                f"{shown}: calibration.parameters[{i}]: {key!r} is not a rig or sample key"
                + did_you_mean(key, known),
                'write it as "rig.KEY" or "sample.KEY", e.g. "rig.thermal_mass_J_per_K"',
            )
        si = keys[name][0]
        if (where, si) in out:
            raise ConfigError(f"{shown}: calibration.parameters[{i}]: {key!r} is listed twice")
        value = getattr(sample if where == "sample" else rig, si)
        log = table.coordinates[i] == "log" if i < len(table.coordinates) else False
        if value is None or (log and not value > 0):
            raise ConfigError(
                f"{shown}: calibration.parameters[{i}]: {key} has "
                + (
                    "no value"
                    if value is None
                    else f"the value {value!r}, not positive as a log coordinate needs"
                ),
                f"state it in [{where}]",
            )
        out.append((where, si))
    return out


def _correlation_matrix(rows: list[list[float]], n: int, shown: str) -> np.ndarray:
    """The ``calibration.correlation`` matrix, checked to be a correlation matrix of size ``n``."""
    if len(rows) != n or any(len(r) != n for r in rows):
        raise ConfigError(
            f"{shown}: calibration.correlation: expected {n} rows of {n} numbers (one per parameter)"
        )
    c = np.array(rows, float)
    bad = np.argwhere(~np.isfinite(c) | (np.abs(c) > 1.0 + 1e-9))
    if bad.size:
        i, j = bad[0]
        raise ConfigError(f"{shown}: calibration.correlation[{i}][{j}] = {rows[i][j]!r} is not in [-1, 1]")
    off = np.argwhere((np.abs(c - c.T) > 1e-6) | (np.eye(n, dtype=bool) & (np.abs(c - 1.0) > 1e-6)))
    if off.size:
        i, j = off[0]
        what = "the diagonal must be 1" if i == j else f"differs from calibration.correlation[{j}][{i}]"
        raise ConfigError(f"{shown}: calibration.correlation[{i}][{j}] = {rows[i][j]!r}: {what}")
    if np.linalg.eigvalsh((c + c.T) / 2).min() < -1e-6:
        raise ConfigError(
            f"{shown}: calibration.correlation is not positive semi-definite",
            "write the matrix tcamlab calibrate reports, not edited entries",
        )
    return c


def _calibration(
    table: _CalibrationTable | None, sample: Sample, rig: Rig, shown: str
) -> CalibratedJoint | None:
    """``[calibration]`` checked against the file's values: equal lengths, finite sds, a correlation matrix."""
    if table is None:
        return None
    n = len(table.parameters)
    for name in ("coordinates", "sd", "sd_below", "sd_above"):
        got = getattr(table, name)
        if got is not None and len(got) != n:
            raise ConfigError(
                f"{shown}: calibration.{name}: {len(got)} entries for {n} parameters",
                "one entry per calibration.parameters entry, in the same order",
            )
    if (table.sd_below is None) != (table.sd_above is None):
        raise ConfigError(
            f"{shown}: calibration: sd_below and sd_above go together", "give both (or neither)"
        )
    fields = _calibration_fields(table, sample, rig, shown)
    sds = {name: _calibration_sds(table, name, fields, shown) for name in ("sd", "sd_below", "sd_above")}
    c = _correlation_matrix(table.correlation, n, shown)
    return CalibratedJoint(
        keys=tuple(table.parameters),
        fields=tuple(fields),
        log=tuple(x == "log" for x in table.coordinates),
        sd=sds["sd"],
        correlation=tuple(tuple(float(x) for x in row) for row in c),
        sd_below=sds["sd_below"],
        sd_above=sds["sd_above"],
    )


def _calibration_sds(table: _CalibrationTable, name: str, fields, shown: str) -> tuple[float, ...] | None:
    """``calibration.<name>`` as fitted-coordinate sds: relative for log, SI for linear; non-negative."""
    values = getattr(table, name)
    if values is None:
        return None
    out = []
    for i, value in enumerate(values):
        v = _finite(shown, f"calibration.{name}[{i}]", value)
        if v < 0:
            raise ConfigError(f"{shown}: calibration.{name}[{i}] = {value!r} must not be negative")
        key = table.parameters[i].partition(".")[2]
        factor = {"rig": RIG_KEYS, "sample": SAMPLE_KEYS}[fields[i][0]][key][1]
        out.append(v if table.coordinates[i] == "log" else v * factor)
    return tuple(out)


# Rig fields that must be positive / non-negative; ambient above absolute zero.
_RIG_POSITIVE = (
    "resistance",
    "thermal_mass",
    "heat_loss",
    "initial_resistance",
    "spring_constant",
    "sensor_offset",
    "stretch_factor",
)
_RIG_POSITIVE_WHY = {
    "stretch_factor": "k_s scales chapter 3's stretch sensitivity of R (1: tcamlab's law); "
    "e.g. stretch_factor = 1",
    "sensor_offset": "d1 is the distance between the sensor and the cable; eq. (4.1) divides by it, "
    "and a sensor on the cable's line would not see the bend",
}
_RIG_NONNEGATIVE = ("load", "pulse", "damping", "lead_resistance")
_RIG_NONNEGATIVE_WHY = {
    "lead_resistance": "R_lead of the leads and contacts in series is 0 or more; "
    "e.g. lead_resistance_ohm = 0.3",
}
_SI_TO_RIG_KEY = {si: key for key, (si, _) in RIG_KEYS.items()}
_RIG_RANGES = {
    "ambient": (-60.0, 100.0, "the room or chamber the rig stands in; e.g. ambient_C = 20"),
    "stretch_factor": (0.0, 10.0, "k_s scales chapter 3's stretch sensitivity of R (1: tcamlab's law); "
                       "e.g. stretch_factor = 1"),
}  # fmt: skip
"""Rig fields whose value must lie in a physical range [SI]: (low, high, why and an example)."""


def _check_range(name: str, value: float, table: Mapping[str, Any], shown: str) -> None:
    """Refuse a rig value outside :data:`_RIG_RANGES` (an ambient of -273 or 150 degC was
    accepted, and a stretch factor of 1e6), naming the key."""
    if name not in _RIG_RANGES:
        return
    lo, hi, why = _RIG_RANGES[name]
    if not lo <= value <= hi:
        key = _SI_TO_RIG_KEY[name]
        raise ConfigError(f"{shown}: rig.{key} = {table[key]!r} is outside {lo:g} to {hi:g}", why)


def _build_rig(doc: _ExperimentFile, shown: str) -> tuple[Rig, dict[str, str]]:
    table = doc.rig.model_dump(exclude_none=True) if doc.rig else {}
    unc_table = table.pop("uncertainty", None) or {}
    overrides = _rig_values(table, shown, "rig", sd=False)
    unc = _rig_values(unc_table, shown, "rig.uncertainty", sd=True)
    for name, value in overrides.items():
        key = _SI_TO_RIG_KEY[name]
        if name in _RIG_POSITIVE and value <= 0:
            raise ConfigError(
                f"{shown}: rig.{key} = {table[key]!r} must be positive",
                _RIG_POSITIVE_WHY.get(name, "a physical magnitude; check the unit in the key name"),
            )
        if name in _RIG_NONNEGATIVE and value < 0:
            raise ConfigError(
                f"{shown}: rig.{key} = {table[key]!r} must not be negative", _RIG_NONNEGATIVE_WHY.get(name)
            )
        _check_range(name, value, table, shown)
    for name, value in unc.items():
        if not isinstance(value, tuple) and value < 0:
            key = _SI_TO_RIG_KEY[name]
            raise ConfigError(
                f"{shown}: rig.uncertainty.{key} = {unc_table[key]!r} must not be negative",
                "uncertainties are standard deviations",
            )

    preset_name = doc.sample.preset if doc.sample else None
    provenance: dict[str, str] = {}
    for f in Rig.__dataclass_fields__:
        if f != "uncertainty":
            provenance[f] = RIG_DEFAULT
    if preset_name is not None:
        preset = get_preset(preset_name)
        rig = preset.build_rig(uncertainty=unc, **overrides)
        provenance.update({k: v.provenance for k, v in preset.rig.items()})
        provenance.update({f"sd({k})": v.provenance for k, v in preset.uncertainty.items()})
    else:
        rig = Rig(uncertainty=dict(unc), **overrides)
    provenance.update({k: EXPERIMENT_FILE for k in overrides})
    provenance.update({f"sd({k})": EXPERIMENT_FILE for k in unc})
    return rig, provenance


# --- writing --------------------------------------------------------------------

_BARE_KEY = re.compile(r"^[A-Za-z0-9_-]+$")
_INLINE_TABLES_IN = {"columns"}


def _key(k: str) -> str:
    return k if _BARE_KEY.match(k) else _string(k)


def _string(s: str) -> str:
    out = ['"']
    for ch in s:
        if ch == '"':
            out.append('\\"')
        elif ch == "\\":
            out.append("\\\\")
        elif ch == "\n":
            out.append("\\n")
        elif ch == "\t":
            out.append("\\t")
        elif ch == "\r":
            out.append("\\r")
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04x}")
        else:
            out.append(ch)
    out.append('"')
    return "".join(out)


def _value(v: Any, where: str) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(float(v))
    if isinstance(v, (str, os.PathLike)):
        return _string(os.fspath(v))
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_value(x, f"{where}[]") for x in v) + "]"
    if isinstance(v, Mapping):
        items = [f"{_key(str(k))} = {_value(x, f'{where}.{k}')}" for k, x in v.items() if x is not None]
        return "{ " + ", ".join(items) + " }" if items else "{}"
    if hasattr(v, "item"):  # numpy scalar
        return _value(v.item(), where)
    raise TypeError(f"cannot write {where} = {v!r} ({type(v).__name__}) to TOML")


def dumps_toml(data: Mapping[str, Any]) -> str:
    """Serialise a mapping to a TOML document.

    Supports str, int, float (including inf/nan), bool, path-like (as
    string), lists/tuples of those, and nested mappings. Nested mappings are
    written as ``[table]`` sections, except the values of ``[columns]``,
    which become inline tables. Keys with value None are omitted (TOML has
    no null).

    Parameters
    ----------
    data : mapping
        The document.

    Returns
    -------
    str
        TOML text ending with a newline.
    """
    lines: list[str] = []

    def emit(table: Mapping[str, Any], path: tuple[str, ...]) -> None:
        inline = bool(path) and path[-1] in _INLINE_TABLES_IN
        scalars = [
            (k, v) for k, v in table.items() if v is not None and (inline or not isinstance(v, Mapping))
        ]
        tables = [(k, v) for k, v in table.items() if isinstance(v, Mapping) and not inline]
        if path and (scalars or not tables):
            if lines:
                lines.append("")
            lines.append("[" + ".".join(_key(p) for p in path) + "]")
        for k, v in scalars:
            lines.append(f"{_key(str(k))} = {_value(v, '.'.join(path + (str(k),)))}")
        for k, v in tables:
            emit(v, path + (str(k),))

    emit(data, ())
    return "\n".join(lines) + "\n"


def write_experiment(path: str | os.PathLike, data: Mapping[str, Any], *, comment: str | None = None) -> Path:
    """Write an experiment (or any) TOML document.

    Parameters
    ----------
    path : path-like
        Destination; parent directories are created. Written atomically
        (temporary file, then rename).
    data : mapping
        The document, e.g. ``{"kind": "dynamic", "title": ..., "runs": [...],
        "sample": {"preset": "thesis-tca"}, "rig": {"load_g": 50.0},
        "columns": {"time_s": {"from": "t", "unit": "ms"}}}``.
    comment : str, optional
        Text written as ``#`` comment lines at the top.

    Returns
    -------
    pathlib.Path
        The written file.
    """
    p = Path(path)
    text = dumps_toml(data)
    if comment:
        text = "".join(f"# {line}".rstrip() + "\n" for line in comment.splitlines()) + "\n" + text
    from tcamlab.report.atomic import atomic_write_text

    return atomic_write_text(p, text)
