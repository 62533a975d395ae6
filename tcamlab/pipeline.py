"""Pipeline: the CLI's commands as library calls that write files.

Each function takes paths and options, calls the library (config -> io ->
models -> metrics -> report) and returns a result object; the CLI only parses
arguments and prints. Every file is written atomically, byte-identical for
identical inputs (no timestamps, no absolute paths).
"""

from __future__ import annotations

import dataclasses
import io as _stdio
import json
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import quote

import pandas as pd

from tcamlab.config import Experiment, load_experiment
from tcamlab.errors import ConfigError, InputError, TcamlabError
from tcamlab.jsonutil import dumps_json
from tcamlab.kinds import KINDS
from tcamlab.report.atomic import atomic_write_bytes, atomic_write_text, write_all_or_nothing

__all__ = [
    "validate_experiment",
    "ValidateOutcome",
    "build_reports",
    "report_names",
    "ReportOutcome",
    "fit_spring_files",
    "simulate_experiment",
    "diagnose_experiment",
    "DiagnoseOutcome",
    "benchmark_diagnosis",
    "list_effects",
    "EffectListing",
    "neutralise_csv",
    "FORMATS",
    "KINDS",
]

FORMATS = ("html", "pdf")
FIGURE_FORMATS = ("png", "svg")
"""Extra ``--format`` values: every figure of the report also as a standalone file,
``figures/figN.png`` (150 dpi) and ``figures/figN.svg``, in the report folder."""


_FORMULA_START = ("=", "+", "-", "@", "\t", "\r")


def neutralise_csv(df: pd.DataFrame) -> pd.DataFrame:
    """Prefix text cells that a spreadsheet would run as a formula (= + - @) with '.

    Only text cells change: numeric columns (negative numbers included) are
    left as numbers. Text columns may be ``object`` or pandas' string dtype
    (the default for text from pandas 3 on), so the test is "not numeric",
    not ``dtype == object``.
    """
    out = df.copy()
    for col in out.columns:
        series = out[col]
        if pd.api.types.is_numeric_dtype(series) or pd.api.types.is_bool_dtype(series):
            continue
        out[col] = series.map(lambda v: "'" + v if isinstance(v, str) and v.startswith(_FORMULA_START) else v)
    out.columns = [("'" + c) if str(c)[:1] in ("=", "+", "-", "@") else c for c in out.columns]
    return out


FAST_CSV_ROWS = 200_000
"""A table longer than this is written by :func:`tcamlab.io.csvfast.fixed_csv_bytes` (fixed
point, 9 significant digits of each column's largest value) instead of pandas (%.9g),
which needs minutes for a 10-million-row log."""


def _csv_bytes(df: pd.DataFrame) -> bytes:
    if len(df) > FAST_CSV_ROWS and list(df.columns[:1]) == ["run"]:
        from tcamlab.io.csvfast import fixed_csv_bytes

        def safe(text):  # a run name made safe once per run, not once per row
            return neutralise_csv(pd.DataFrame({"run": [text]}))["run"].iloc[0]

        header = neutralise_csv(df.iloc[:0]).to_csv(index=False, lineterminator="\n").encode()
        return fixed_csv_bytes(df, label="run", text=safe, header=header)
    buf = _stdio.StringIO()
    neutralise_csv(df).to_csv(buf, index=False, float_format="%.9g", lineterminator="\n")
    return buf.getvalue().encode()


@dataclass
class ValidateOutcome:
    """What ``validate`` produced for one experiment."""

    result: object
    out_dir: Path
    files: list = field(default_factory=list)

    @property
    def passed(self) -> bool | None:
        """True / False when thresholds were checked, None when none was set."""
        return self.result.passed

    @property
    def failed(self) -> bool:
        """A threshold failed."""
        return self.result.failed


def _parse_formats(formats: Sequence[str] | str) -> tuple[str, ...]:
    if isinstance(formats, str):
        formats = [f.strip() for f in formats.split(",") if f.strip()]
    bad = [f for f in formats if f not in FORMATS + FIGURE_FORMATS]
    if bad:
        raise ConfigError(
            f"--format: unknown format {bad[0]!r}",
            hint="use html, pdf or html,pdf (add png and/or svg for standalone figures)",
        )
    return tuple(formats)


def validate_experiment(
    path,
    out_dir="reports",
    *,
    expected_kind: str | None = None,
    formats=FORMATS,
    mc_draws: int | None = None,
    drop_na: bool = False,
    max_bytes: int | None = None,
    command: str | None = None,
    out_name: str | None = None,
    force: bool = False,
    ignore=(),
) -> ValidateOutcome:
    """Validate one experiment and write ``out_dir/NAME/{report.html, report.pdf,
    metrics.json, predictions.csv}`` (NAME: ``out_name``, default the file stem, or its
    path when another experiment file of that stem wrote ``out_dir/STEM``; see
    :func:`output_folder`). An existing report of the experiment is replaced only with
    ``force``, checked before the validation runs.

    Parameters
    ----------
    path : path-like
        Experiment TOML.
    out_dir : path-like
        Parent directory of the report folder.
    expected_kind : str, optional
        The ``validate`` subcommand's kind; a mismatch is a ConfigError.
    formats : str or sequence
        Report formats among html, pdf.
    mc_draws : int, optional
        Monte Carlo draws for dynamic runs (default :data:`validation.MC_DRAWS`).
    drop_na : bool
        Drop rows with blank cells (counted in the report).
    max_bytes : int, optional
        Refuse run files larger than this [bytes] (default
        :data:`tcamlab.io.DEFAULT_MAX_BYTES`).
    command : str, optional
        Command line shown in the report's provenance.
    out_name : str, optional
        The report folder's name, chosen by the caller (``report``: :func:`report_names`);
        then an existing report there is replaced.
    force : bool
        Replace an existing report of this experiment.
    ignore : iterable of str
        Canonical optional columns treated as not logged (``--ignore load_N``); checked
        against the kind's data contract before anything is read or written.

    Returns
    -------
    ValidateOutcome
    """
    from tcamlab import validation

    formats = _parse_formats(formats)
    exp = load_experiment(path, expected_kind=expected_kind)
    ignore = validation.ignored_columns(exp.kind, ignore)
    if out_name is None:
        target = output_folder(out_dir, [exp.path], "metrics.json", force=force)
    else:
        target = Path(out_dir) / out_name
    kw = {} if mc_draws is None else {"mc_draws": mc_draws}
    result = validation.validate(exp, drop_na=drop_na, max_bytes=max_bytes, ignore=ignore, **kw)
    files = _write_validation(result, target, formats, command)
    return ValidateOutcome(result, target, files)


def _write_validation(result, target: Path, formats, command) -> list[Path]:
    from tcamlab.report.validation_report import validation_document

    # Compute everything first, then write: a failure leaves no partial report.
    doc = validation_document(result, command=command)
    payload = {
        "metrics.json": dumps_json(result.to_dict()).encode(),
        "predictions.csv": _csv_bytes(result.to_pandas()),
    }
    if "html" in formats:
        from tcamlab.report.html import render_html

        payload["report.html"] = render_html(doc).encode()
    if "pdf" in formats:
        from tcamlab.report.pdf import render_pdf

        payload["report.pdf"] = render_pdf(doc)
    payload |= _standalone_figures(doc, payload.get("report.html"), formats)
    if any(name.startswith("figures/") for name in payload):
        (target / "figures").mkdir(parents=True, exist_ok=True)
    files = write_all_or_nothing(target, payload)
    result.document = doc
    return files


def _standalone_figures(doc, html: bytes | None, formats) -> dict[str, bytes]:
    """``figures/figN.png`` / ``.svg`` for the requested :data:`FIGURE_FORMATS` (the SVGs
    are the ones inlined in the HTML when there is one, with an XML declaration)."""
    wanted = [f for f in FIGURE_FORMATS if f in formats]
    if not wanted:
        return {}
    from tcamlab.report.calibration_report import figure_files

    files = figure_files(doc, html.decode() if html else None, stem="fig")
    out = {}
    for name, data in files.items():
        ext = name.rsplit(".", 1)[1]
        if ext in wanted:
            if ext == "svg":
                data = b'<?xml version="1.0" encoding="utf-8" standalone="no"?>\n' + data
            out["figures/" + name.replace("fig-fig", "fig")] = data
    return out


@dataclass
class ReportOutcome:
    """What ``report`` produced."""

    out_dir: Path
    entries: list
    index_path: Path
    pdf_path: Path | None

    @property
    def failed(self) -> list:
        """Entries with a failed threshold (not those without limits, nor errors)."""
        return [e for e in self.entries if e.status == "fail"]


def _headline(result) -> dict[str, str]:
    """The index's headline metrics: the primary model's pooled RMSE (with unit) and R²,
    one line per quantity (the rest is in each report)."""
    from tcamlab.numbers import bare_name, fmt_r2, rmse_unit, unit_label, with_unit

    lines: dict[str, list[str]] = {"Quantity": [], "RMSE": [], "R²": []}
    for q, block in result.metrics[result.primary].items():
        m = block["pooled"]
        lines["Quantity"].append(bare_name(q))
        # as the diagnosis prints them: a load-cell RMSE in mN, a curvature's in 1/m
        shown, factor = rmse_unit(unit_label(q))
        lines["RMSE"].append(with_unit(m["rmse"] * factor, shown))
        lines["R²"].append(fmt_r2(m["r2"]))
    return {k: "\n".join(v) for k, v in lines.items()}


def build_reports(
    paths: Sequence | None = None,
    out_dir="reports",
    *,
    experiments_dir="experiments",
    mc_draws: int | None = None,
    drop_na: bool = False,
    max_bytes: int | None = None,
    progress: Callable[[str, int, int], None] | None = None,
) -> ReportOutcome:
    """Validate every experiment, write each report, ``index.html`` and one combined PDF.

    An experiment that fails to load or validate is listed in the index with
    its one-line error and gets no new report files; the others still build.
    ``drop_na`` and ``max_bytes`` are passed to every experiment's
    :func:`validate_experiment`.
    """
    from tcamlab.report.document import IndexEntry
    from tcamlab.report.html import render_index_html
    from tcamlab.report.pdf import render_combined_pdf

    if not paths:
        folder = Path(experiments_dir)
        paths = sorted(folder.glob("*.toml"))
        if not paths:
            raise ConfigError(
                f"{folder}: no experiment files (*.toml) found",
                hint="pass experiment files or use --experiments DIR",
            )
    out = Path(out_dir)
    entries, results = [], []
    names = report_names(paths)
    # report rebuilds its folders (named for the whole set): each is replaced
    kw = {"mc_draws": mc_draws, "drop_na": drop_na, "max_bytes": max_bytes, "command": None}
    for i, p in enumerate(paths):
        p = Path(p)
        if progress:
            progress(p.name, i, len(paths))
        try:
            outcome = validate_experiment(p, out, out_name=names[i], **kw)
        except TcamlabError as exc:
            entries.append(IndexEntry(names[i], p.stem, "?", "error", {}, link=None, error=exc.one_line()))
            continue
        entries.append(_index_entry(outcome.result, names[i]))
        results.append(outcome.result)
    index = _index_document(entries, results, paths)
    index_path = atomic_write_text(out / "index.html", render_index_html(index))
    docs = [r.document for r in results]
    pdf_path = atomic_write_bytes(out / "reports.pdf", render_combined_pdf(docs, index))
    return ReportOutcome(out, entries, index_path, pdf_path)


def _sha256_or(path) -> str:
    from tcamlab.io import sha256_file

    try:
        return sha256_file(path)
    except OSError:
        return "unreadable"


def _index_entry(res, name: str):
    """The index row of one validation; ``name`` is its report folder (see :func:`report_names`)."""
    from tcamlab.report.document import IndexEntry

    return IndexEntry(
        name=name,
        title=res.experiment.title,
        kind=res.kind,
        status=INDEX_STATUS[res.status],
        metrics=_headline(res),
        link=f"{quote(name)}/report.html",
        error=None,
        warnings=[w.message for w in res.warnings],
    )


def _index_document(entries, results, paths):
    """The index: entries, the synthetic banner when any input is synthetic, and provenance
    (tool version, each experiment file's path relative to the working folder and SHA-256)."""
    from tcamlab import __version__
    from tcamlab.report.document import IndexDocument
    from tcamlab.validation import relative_to

    metadata = {"tool": f"tcamlab {__version__}", "experiments": str(len(entries))}
    for name, p in zip(report_names(paths), paths):
        p = Path(p)
        metadata[f"experiment {name}"] = relative_to(p, Path.cwd())
        metadata[f"sha256 {name}"] = _sha256_or(p)
    synthetic = [r.experiment.name for r in results if r.experiment.synthetic]
    banner = None
    if synthetic:
        banner = (
            f"SYNTHETIC DATA: {len(synthetic)} of {len(entries)} experiments ({', '.join(synthetic)}) "
            "were made by the virtual rig (tcamlab simulate), not measured; each report names its "
            "generator, seed and command."
        )
    return IndexDocument(
        title="tcamlab validation reports", entries=entries, metadata=metadata, synthetic_banner=banner
    )


INDEX_STATUS = {"passed": "pass", "failed": "fail", "no limits set": "no-limits"}
"""Validation status -> index status (:data:`tcamlab.report.document.INDEX_STATUSES`)."""


PLOT_FORMATS = (".png", ".svg", ".pdf")
"""Extensions ``fit-spring --plot`` writes; the extension names the format."""


def report_names(paths: Sequence) -> list[str]:
    """The report folder of each experiment file: its stem, or where two files share a stem
    (``lab1/case.toml``, ``lab2/case.toml``), its path below their common folder joined
    with ``-`` (``lab1-case``, ``lab2-case``), so no report overwrites another."""
    resolved = [Path(p).resolve() for p in paths]
    stems = [p.stem for p in resolved]
    names = []
    for p, stem in zip(resolved, stems):
        same = [q for q in resolved if q.stem.lower() == stem.lower()]
        if len(set(same)) <= 1:
            names.append(stem)
            continue
        common = Path(os.path.commonpath([q.parent for q in same]))
        names.append("-".join(p.relative_to(common).with_suffix("").parts))
    seen: dict[str, int] = {}
    for i, n in enumerate(names):  # the same file given twice: one folder each
        seen[n] = seen.get(n, 0) + 1
        if seen[n] > 1:
            names[i] = f"{n}-{seen[n]}"
    return names


def recorded_experiments(record: Path) -> list[Path] | None:
    """The experiment files an output was made from, as its JSON record lists them
    (``metrics.json``, ``diagnosis.json``, ``calibration.json``), resolved against the
    working folder; None when the record names none, or a file outside the working folder
    (``.../NAME``: reports hold no absolute paths), or cannot be read."""
    import json

    try:
        doc = json.loads(record.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(doc, dict):
        return None
    if record.name == "metrics.json":
        found = [(doc.get("experiment_file") or {}).get("path")]
    elif record.name == "diagnosis.json":
        found = [(doc.get("experiment") or {}).get("path")]
    else:
        found = [i.get("path") for i in doc.get("inputs") or [] if i.get("role") == "experiment"]
    if not found or not all(isinstance(f, str) and f and not f.startswith(".../") for f in found):
        return None
    return [Path(f).resolve() for f in found]


def output_folder(out_dir, paths: Sequence, record: str, *, force: bool = False) -> Path:
    """``out_dir/NAME``, the folder of a command's outputs for the experiment files ``paths``.

    NAME is :func:`report_names` of the files (joined with ``+``), so a file is named by its
    stem; when ``out_dir/STEM`` holds the outputs (``record``, e.g. ``metrics.json``) of
    another experiment file of that stem (``lab1/case.toml`` then ``lab2/case.toml``), the
    files are named by their path as :func:`report_names` names the two (``lab2-case``).
    Outputs of the same files, or of files the record cannot tell (an experiment file
    outside the working folder), are replaced only with ``force``.

    Raises
    ------
    InputError
        The folder holds that command's outputs of these files (or of files it cannot tell),
        and not ``force``.
    """
    paths = [Path(p).resolve() for p in paths]
    folder = Path(out_dir) / "+".join(report_names(paths))
    owners = recorded_experiments(folder / record) if (folder / record).exists() else None
    if owners is not None and owners != paths:
        # another experiment file of the same stem: one folder each, named by path
        names = report_names([*owners, *paths])[len(owners) :]
        folder = Path(out_dir) / "+".join(names)
    if (folder / record).exists() and not force:
        raise InputError(
            f"{folder / record}: exists, from an earlier run of this experiment",
            "pass --force to overwrite it, or --out another folder",
        )
    return folder


def fit_spring_files(
    paths: Sequence,
    *,
    intercept: bool = True,
    robust: bool = False,
    by_branch: bool = True,
    plot_path=None,
    drop_na: bool = False,
    max_bytes: int | None = None,
    force: bool = False,
    columns=None,
):
    """Identify S of F = S delta + F0 from pull-test CSVs or sensing experiment files.

    Returns a :class:`tcamlab.fitting.SpringFitReport` (F0, the load cell's
    zero, is one nuisance per run unless ``intercept=False`` forces the fit
    through the origin). Writes the fit and residual plot to ``plot_path`` if
    given, in the format its extension names (:data:`PLOT_FORMATS`), never
    over an existing file unless ``force``.
    A bare CSV needs only ``displacement_mm`` and ``force_N``, mapped by ``columns``
    (a ``[columns]`` table, or ``CANON=HEADER[:UNIT]`` strings, the CLI's ``--column``). ``drop_na`` and ``max_bytes`` are
    passed to :func:`tcamlab.io.read_run`.

    Raises
    ------
    InputError
        No runs, an unreadable run, an unknown plot extension, or an existing plot without ``force``.
    """
    from tcamlab.fitting import fit_spring_runs

    if plot_path is not None:
        _check_plot_path(Path(plot_path), force)
    frames = _pull_frames(paths, drop_na, max_bytes, columns)
    runs = _pull_runs(frames)
    report = fit_spring_runs(runs, intercept=intercept, robust=robust, by_branch=by_branch)
    _refuse_negative_spring(report, frames)
    if plot_path is not None:
        import matplotlib

        # Run names come from file names: '$' must not start matplotlib mathtext.
        with matplotlib.rc_context({"text.parse_math": False}):
            fig, (ax1, ax2) = _two_axes()
            report.plot(ax1)
            report.plot_residuals(ax2)
        atomic_write_bytes(Path(plot_path), _figure_bytes(fig, Path(plot_path).suffix.lower()))
    return report


def _check_plot_path(path: Path, force: bool) -> None:
    if path.suffix.lower() not in PLOT_FORMATS:
        raise InputError(
            f"--plot {path.name}: unknown plot format {path.suffix or '(no extension)'!r}",
            hint="end the file name in " + ", ".join(PLOT_FORMATS),
        )
    if path.exists() and not force:
        raise InputError(f"--plot {path}: file exists", hint="pass --force to overwrite it")


def _refuse_negative_spring(report, frames) -> None:
    """A negative S is no spring constant: name the likely cause instead of reporting it."""
    from tcamlab.fitting import starts_under_load
    from tcamlab.io import sign_flip_entry

    s = report.pooled.spring_constant
    if not s < 0:
        return
    files = ", ".join(str(r.path) for r in frames)
    released = [r.path.name for r in frames if starts_under_load(r.data["force"].to_numpy(float))]
    segment = (
        f"; {', '.join(released)} starts under load (a release or unloading segment, preloaded)"
        if released
        else ""
    )
    raise InputError(
        f"fit-spring: {files}: S = {s:.5g} N/m is negative (the force falls as the sample is stretched), "
        f"so it is not reported as a spring constant{segment}",
        hint=f"the likely cause is the force column's sign: map it in [columns] as "
        f"{sign_flip_entry(frames[0], 'force_N')}; or the displacement runs the other way in "
        "a release/unloading segment: fit a loading segment, stretched from its unloaded length",
    )


def _pull_frames(paths: Sequence, drop_na: bool, max_bytes: int | None, columns=None) -> list:
    """Every pull test in CSVs or sensing experiment files, read; a bare CSV needs only
    displacement and force, mapped by ``columns`` (see fit_spring_files)."""
    from tcamlab import io as tio

    read_kw: dict = {"drop_na": drop_na}
    if max_bytes is not None:
        read_kw["max_bytes"] = max_bytes
    if columns is not None and not isinstance(columns, dict):
        columns = dict(tio.column_option(c) for c in columns)
    frames = []
    for p in paths:
        p = Path(p)
        if p.suffix.lower() == ".toml":
            frames.extend(load_experiment(p, expected_kind="sensing").read_runs(**read_kw))
        else:
            frames.append(tio.read_run(p, "sensing", columns, only=("displacement_mm", "force_N"), **read_kw))
    return frames


def _pull_runs(frames: list) -> list:
    """(name, displacement [m], force [N]) of every pull test read."""
    runs = [
        (r.path.stem, r.data["displacement"].to_numpy(float), r.data["force"].to_numpy(float)) for r in frames
    ]
    if not runs:
        raise InputError("fit-spring: no runs given", hint="pass CSV files or experiment files")
    names = [n for n, _, _ in runs]
    if len(set(names)) != len(names):
        runs = [(f"{i + 1}:{n}", x, f) for i, (n, x, f) in enumerate(runs)]
    return runs


def _figure_bytes(fig, suffix: str) -> bytes:
    """A figure as PNG, SVG or PDF bytes, without dates (same input, same bytes)."""
    from tcamlab.report.figures import figure_to_png, figure_to_svg, replace_missing_glyphs

    replace_missing_glyphs(fig)
    if suffix == ".png":
        return figure_to_png(fig)
    if suffix == ".svg":
        return figure_to_svg(fig).encode()
    buf = _stdio.BytesIO()
    fig.savefig(buf, format="pdf", metadata={"CreationDate": None, "ModDate": None})
    return buf.getvalue()


def _two_axes():
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6.4, 6.0), layout="constrained")
    ax1, ax2 = fig.subplots(2, 1)
    return fig, (ax1, ax2)


# -- simulate ---------------------------------------------------------------------------


def _assignments(items, flag: str, form: str, example: str) -> dict[str, float] | None:
    """Parse repeated NAME=NUMBER options into a dict (None when there are none)."""
    if items is None or isinstance(items, dict):
        return items or None
    out = {}
    for item in items:
        key, sep, value = item.partition("=")
        try:
            out[key.strip()] = float(value)
        except ValueError:
            raise ConfigError(f"{flag} {item!r}: expected {form}", hint=f"e.g. {flag} {example}") from None
        if not sep:
            raise ConfigError(f"{flag} {item!r}: expected {form}")
    return out or None


def _check_kind(kind: str, flag: str = "kind") -> None:
    from tcamlab.text import did_you_mean

    if kind not in KINDS:
        raise ConfigError(
            f"unknown {flag} {kind!r}{did_you_mean(kind, KINDS)}", hint="one of " + ", ".join(KINDS)
        )


def simulate_experiment(
    kind: str,
    experiment,
    *,
    seed: int,
    out_dir,
    effects=None,
    runs: int | None = None,
    name: str | None = None,
    scatter=None,
    noise_scale: float = 1.0,
    oven: str = "heating",
    parameter_error: float = 0.0,
    noisy_zero: bool = False,
    conditions: int = 1,
    truth=None,
    force: bool = False,
):
    """Virtual rig: write ``out_dir/{experiments,raw,truth}/`` for one simulated experiment.

    Existing files are never replaced unless ``force`` (checked before anything is written).

    ``experiment`` is a template experiment file, or a bare kind ('static')
    naming the template shipped in :mod:`tcamlab.templates`. ``effects`` and
    ``scatter`` are dicts or ``NAME=NUMBER`` strings (the CLI's repeated
    options): effect strengths in noise RMS, relative scatter of Sample/Rig
    fields. ``parameter_error`` and ``noisy_zero`` make the rig lie like a
    real lab (:func:`tcamlab.rig.simulate`); ``conditions`` 2 alternates the runs between
    the stated condition and the kind's second (:data:`tcamlab.rig.CONDITIONS`). ``truth``,
    the truth file of an earlier simulation, measures the same muscle again
    (:func:`tcamlab.rig.same_truth`: its effects, true parameters, zeros and scatter; new noise);
    it replaces ``effects``, ``parameter_error``, ``noisy_zero``, ``scatter`` and ``noise_scale``.
    Returns :class:`tcamlab.rig.SimulationResult`.
    """
    from tcamlab import rig
    from tcamlab.templates import resolve_template
    from tcamlab.text import simulate_command

    _check_kind(kind)
    effects = _assignments(effects, "--effect", "NAME=STRENGTH", "glass-transition=3 (3x the noise RMS)")
    scatter = _assignments(scatter, "--scatter", "FIELD=REL", "twists=0.002 (0.2% between runs)")
    command = simulate_command(
        kind,
        experiment,
        seed,
        out_dir,
        runs=runs,
        name=name,
        noise_scale=noise_scale,
        oven=oven,
        scatter=scatter,
        effects=effects,
        parameter_error=parameter_error,
        noisy_zero=noisy_zero,
        conditions=conditions,
        truth=truth,
    )
    template = resolve_template(experiment)
    _refuse_simulation_overwrite(kind, template, out_dir, runs, name, force)
    opts = dict(effects=effects or {}, scatter=scatter, noise_scale=noise_scale)
    opts.update(parameter_error=parameter_error, noisy_zero=noisy_zero)
    if truth is not None:
        opts, doc = _same_truth(kind, truth, effects, parameter_error, noisy_zero)
        # a protocol file made from a simulated experiment lacks the rig values it kept hidden
        template = rig.with_hidden_rig(load_experiment(template, require_runs=False), doc)
    return rig.simulate(
        kind,
        template,
        seed=seed,
        out_dir=out_dir,
        n_runs=runs,
        name=name,
        oven=oven,
        command=command,
        conditions=conditions,
        **opts,
    )


def _same_truth(kind: str, path, effects, parameter_error, noisy_zero) -> tuple[dict, dict]:
    """(simulate's arguments from a truth file (:func:`tcamlab.rig.same_truth`), the truth file's
    content); refuses the options the truth file sets."""
    from tcamlab import rig

    given = [o for o, v in (("--effect", effects), ("--parameter-error", parameter_error)) if v]
    given += ["--noisy-zero"] if noisy_zero else []
    if given:
        raise ConfigError(
            f"--truth sets the effects and the rig's lies; {', '.join(given)} would contradict it",
            hint=f"drop {', '.join(given)}, or drop --truth",
        )
    path = Path(path)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise ConfigError(
            f"{path}: cannot read the truth file ({exc})", hint="truth/NAME.truth.json"
        ) from None
    if doc.get("kind") != kind:
        raise ConfigError(f"{path}: a truth file of a {doc.get('kind')!r} simulation, not {kind!r}")
    return rig.same_truth(doc), doc


def _refuse_simulation_overwrite(kind, template, out_dir, runs, name, force) -> None:
    """The files simulate would write must not exist yet (unless ``force``)."""
    from tcamlab.rig import DEFAULT_RUNS
    from tcamlab.rig.writers import output_paths, refuse_overwrite

    if force:
        return
    stem = Path(template).stem if name is None else str(name)
    n = DEFAULT_RUNS[kind] if runs is None else max(int(runs), 1)
    refuse_overwrite(output_paths(out_dir, stem, n), force=force)


# -- diagnose ---------------------------------------------------------------------------


@dataclass
class DiagnoseOutcome:
    """What ``diagnose`` produced: the diagnosis and the files written (if any)."""

    result: object
    experiment: Experiment
    files: list = field(default_factory=list)


def diagnose_experiment(
    path, *, effects=None, seed: int = 0, out_dir=None, force: bool = False, drop_na: bool = False, ignore=()
) -> DiagnoseOutcome:
    """Diagnose the sim-to-real gap of one experiment.

    ``effects`` restricts the candidates (a list, or a comma-separated string);
    ``seed`` seeds the bootstrap. With ``out_dir``, writes
    ``out_dir/NAME/diagnosis.{json,html,pdf}`` all or nothing (NAME as
    :func:`output_folder` names it); an existing diagnosis of the experiment is
    replaced only with ``force``, checked before the diagnosis runs. ``drop_na`` drops
    rows with blank cells (:func:`tcamlab.io.read_run`). ``ignore``: canonical optional columns
    treated as not logged (:func:`tcamlab.validation.ignored_columns`), kept in the result's
    ``settings``.
    """
    from tcamlab import validation
    from tcamlab.diagnosis import diagnose

    exp = load_experiment(path)
    ignore = validation.ignored_columns(exp.kind, ignore)
    folder = (
        output_folder(out_dir, [exp.path], "diagnosis.json", force=force) if out_dir is not None else None
    )
    if isinstance(effects, str):
        effects = [e.strip() for e in effects.split(",") if e.strip()]
    runs = validation.without_columns(exp.read_runs(drop_na=drop_na), ignore)
    result = diagnose(exp, runs, effects=effects or None, seed=seed)
    result.settings = dataclasses.replace(result.settings, ignored_columns=list(ignore))
    result.next_experiment = next_experiment(exp, result.to_dict(), seed=seed)
    files = _write_diagnosis(result, exp, folder) if folder is not None else []
    return DiagnoseOutcome(result, exp, files)


def next_experiment(experiment: Experiment, diagnosis: dict, *, seed: int = 0) -> dict | None:
    """The design of the next experiment for a diagnosis (:func:`tcamlab.design.design`, in its
    JSON layout), or None for a kind without a menu of protocols."""
    from tcamlab.design import design
    from tcamlab.design.protocols import kind_module

    if not hasattr(kind_module(experiment.kind), "design_menu"):
        return None
    return design(experiment, diagnosis, seed=seed).to_dict()


def _write_diagnosis(result, experiment: Experiment, folder) -> list[Path]:
    """Write OUT/NAME/diagnosis.json, diagnosis.html, diagnosis.pdf and each figure as
    standalone diagnosis-figN.png / .svg, all or nothing."""
    from tcamlab.report.calibration_report import figure_files
    from tcamlab.report.diagnosis_report import diagnosis_document
    from tcamlab.report.html import render_html
    from tcamlab.report.pdf import render_pdf

    doc = diagnosis_document(result, experiment)
    html = render_html(doc)
    payload = {
        "diagnosis.json": dumps_json(result.to_dict()).encode(),
        "diagnosis.html": html.encode(),
        "diagnosis.pdf": render_pdf(doc),
    }
    payload.update(figure_files(doc, html, stem="diagnosis"))
    return write_all_or_nothing(Path(folder), payload)


# -- design -------------------------------------------------------------------------------


@dataclass
class DesignOutcome:
    """What :func:`design_experiment` found and wrote."""

    result: object  # tcamlab.design.DesignResult
    experiment: Experiment
    files: list[Path] = field(default_factory=list)


def design_experiment(
    path,
    *,
    diagnosis=None,
    effects=None,
    out_dir=None,
    force: bool = False,
    seed: int = 0,
    drop_na: bool = False,
) -> DesignOutcome:
    """The next protocol that separates what the experiment's diagnosis could not (:mod:`tcamlab.design`).

    ``diagnosis``: a ``diagnosis.json`` of this experiment; default, the experiment is diagnosed
    here (``effects``, ``seed`` and ``drop_na`` as :func:`diagnose_experiment`). Writes the best
    protocol as ``NAME.next.toml`` beside the experiment and ``design.json`` (in ``out_dir/NAME/``,
    else ``NAME.design.json`` beside the experiment); an existing file is replaced only with
    ``force``, checked before anything runs.
    """
    import json

    from tcamlab.design import design, protocol_toml

    exp = load_experiment(path)
    protocol_path = exp.path.with_name(f"{exp.name}.next.toml")
    folder = Path(out_dir) / exp.name if out_dir is not None else exp.path.parent
    json_path = folder / ("design.json" if out_dir is not None else f"{exp.name}.design.json")
    for target in (protocol_path, json_path):
        if target.exists() and not force:
            raise ConfigError(f"{target}: exists (not replaced)", "--force replaces it")
    if diagnosis is not None:
        try:
            found = json.loads(Path(diagnosis).read_text(encoding="utf-8"))
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise ConfigError(f"{diagnosis}: not a diagnosis.json ({exc})") from None
        if found.get("kind") != exp.kind:
            raise ConfigError(f"{diagnosis}: a {found.get('kind')!r} diagnosis of a {exp.kind!r} experiment")
    else:
        from tcamlab.diagnosis import diagnose

        if isinstance(effects, str):
            effects = [e.strip() for e in effects.split(",") if e.strip()]
        found = diagnose(exp, exp.read_runs(drop_na=drop_na), effects=effects or None, seed=seed).to_dict()
    result = design(exp, found, seed=seed)
    folder.mkdir(parents=True, exist_ok=True)
    files = [atomic_write_text(json_path, dumps_json(result.to_dict()))]
    if result.best is not None:
        header = (
            f"{exp.name}: the next protocol ({result.message})\nmade by tcamlab design; what each run "
            "logs, row by row and in time, is in the docs: experiment design, What a run logs"
        )
        atomic_write_text(protocol_path, protocol_toml(exp.raw, result.best.table, header))
        files.append(protocol_path)
    return DesignOutcome(result, exp, files)


# -- benchmark and effects ----------------------------------------------------------------


BENCHMARK_FILES = ("benchmark.json", "benchmark.md", "benchmark.html", "benchmark.pdf")
"""The files a diagnosis benchmark writes in its output folder."""


def benchmark_diagnosis(out_dir, *, kinds=None, effects=None, templates=None, force=False, **options):
    """Withheld-effect benchmark of the diagnosis (:func:`tcamlab.benchmark.run_benchmark`).

    ``kinds`` (default :data:`tcamlab.benchmark.BENCHMARK_KINDS`, or the kinds of
    ``templates``) are checked first, so a typo fails before minutes of simulation;
    ``templates`` are experiment files whose sample and rig replace their kind's bundled
    template (one per kind); ``options`` are ``quick``, ``scheduler``, ``workers``, ``seeds``,
    ``lies``, ``families``, ``conditions``. A folder that already holds a benchmark's files
    is refused before anything runs unless ``force``.
    """
    from tcamlab.benchmark import BENCHMARK_KINDS, run_benchmark
    from tcamlab.rig import CONDITIONS

    existing = [Path(out_dir) / n for n in BENCHMARK_FILES if (Path(out_dir) / n).exists()]
    if existing and not force:
        more = f" (and {len(existing) - 1} more)" if len(existing) > 1 else ""
        raise InputError(f"{existing[0]}: benchmark output exists{more}", "pass --force to overwrite it")
    by_kind = _benchmark_templates(templates or ())
    default = tuple(by_kind) or BENCHMARK_KINDS
    if options.get("conditions", 1) == 2:  # the kinds that have a second condition
        default = tuple(k for k in default if k in CONDITIONS)
    kinds = tuple(kinds) if kinds else default
    for k in kinds:
        _check_kind(k, "--kind")
    _check_effects(effects or (), kinds)
    return run_benchmark(
        out_dir, kinds=kinds, effects=list(effects) if effects else None, templates=by_kind or None, **options
    )


def _benchmark_templates(paths) -> dict:
    """{kind: resolved path} of the ``--template`` files: readable experiment files of a
    benchmarked kind, one per kind."""
    from tcamlab.benchmark import BENCHMARK_KINDS
    from tcamlab.config import load_experiment

    out = {}
    for path in paths:
        exp = load_experiment(path, require_runs=False)
        if exp.kind not in BENCHMARK_KINDS:
            raise ConfigError(
                f"{path}: kind {exp.kind!r} has no diagnosis benchmark",
                hint="--template takes an experiment file of kind " + ", ".join(BENCHMARK_KINDS),
            )
        if exp.kind in out:
            raise ConfigError(
                f"{path}: a second --template of kind {exp.kind!r} (the first: {out[exp.kind]})",
                hint="give one --template per kind",
            )
        out[exp.kind] = Path(path).resolve()
    return out


def _check_effects(effects, kinds) -> None:
    """An unknown effect (or one of none of ``kinds``) is a ConfigError, before any simulation."""
    from tcamlab.effects import EFFECTS
    from tcamlab.text import did_you_mean

    known = sorted({name for kind, name in EFFECTS if kind in kinds})
    for name in effects:
        if name not in known:
            raise ConfigError(
                f"unknown effect {name!r} of {', '.join(kinds)}{did_you_mean(name, known)}",
                hint="tcamlab effects list shows them",
            )


@dataclass
class EffectListing:
    """The unmodelled effects of :func:`list_effects`."""

    effects: list

    def to_records(self) -> list[dict]:
        return [
            {
                "kind": e.kind,
                "name": e.name,
                "cause": e.cause,
                "source": e.source,
                "parameters": [{"name": p.field, "unit": p.unit} for p in e.params],
            }
            for e in self.effects
        ]


def list_effects(kind: str | None = None) -> EffectListing:
    """The unmodelled-effect library, optionally of one rig kind."""
    from tcamlab.effects import EFFECTS

    if kind is not None:
        _check_kind(kind)
    return EffectListing([e for e in EFFECTS.values() if kind is None or e.kind == kind])


# -- calibrate ----------------------------------------------------------------------------


@dataclass
class CalibrateOutcome:
    """What ``calibrate`` produced: the calibration and the files written."""

    result: object
    files: list = field(default_factory=list)


def calibrate_experiment(
    paths,
    *,
    params=None,
    out_dir=None,
    force: bool = False,
    command: str | None = None,
    drop_na: bool = False,
) -> CalibrateOutcome:
    """Calibrate one or more experiments of one sample and write the results.

    Writes ``NAME.calibrated.toml`` beside each experiment file (never the file itself)
    and, with ``out_dir``, ``out_dir/NAME/`` (NAME joins the experiment files' names with
    ``+``, each named as :func:`output_folder` names it)
    with ``calibration.json``, the report ``calibration.html`` and ``calibration.pdf``
    (:mod:`tcamlab.report.calibration_report`) and each report figure as
    ``calibration-figN.png`` / ``.svg``. An existing output is overwritten only with
    ``force``, checked before the calibration runs. Nothing is written unless the
    calibration and the reports succeed; a failed write removes the files just written.
    ``command`` is the command line shown in the report (default: built from the options).
    ``drop_na`` drops rows with blank cells (:func:`tcamlab.io.read_run`).
    """
    from tcamlab.calibration import calibrate, calibrated_path, calibrated_text, load_experiments

    exps = load_experiments(list(paths) if not isinstance(paths, (str, Path)) else [paths])
    targets = [calibrated_path(e) for e in exps]
    for e, t in zip(exps, targets):
        if t == e.path:
            raise InputError(f"{t}: refusing to overwrite the experiment file itself")
    folder = None
    if out_dir is not None:
        folder = output_folder(out_dir, [e.path for e in exps], "calibration.json", force=True)
    if not force:
        _refuse_existing(targets, folder)
    result = calibrate(exps, params, drop_na=drop_na)
    if command is None:
        command = _calibrate_command(exps, params, drop_na)
    payload = _calibration_payload(result, exps, params, command) if folder is not None else {}
    files: list[Path] = []
    try:
        for e, t in zip(exps, targets):
            files.append(atomic_write_text(t, calibrated_text(e, result)))
        if folder is not None:
            files += write_all_or_nothing(folder, payload)
    except BaseException:
        for f in files:
            f.unlink(missing_ok=True)
        raise
    return CalibrateOutcome(result, files)


CALIBRATION_FILES = ("calibration.json", "calibration.html", "calibration.pdf")
"""The fixed files of a calibration's output folder (figures come as calibration-figN.*)."""


def _refuse_existing(targets, folder) -> None:
    """InputError when a calibrated file or a calibration output already exists."""
    existing = [t for t in targets if t.exists()]
    if folder is not None and folder.is_dir():
        existing += [folder / n for n in CALIBRATION_FILES if (folder / n).exists()]
        existing += sorted(folder.glob("calibration-fig*"))
    if existing:
        more = f" (and {len(existing) - 1} more)" if len(existing) > 1 else ""
        raise InputError(f"{existing[0]}: calibration output exists{more}", "pass --force to overwrite it")


def _calibrate_command(exps, params, drop_na: bool) -> str:
    """The calibrate command line shown in the report (the options that change it)."""
    from tcamlab.text import command_line, shown_path

    if params is not None and not isinstance(params, str):
        params = ",".join(params)
    return command_line(
        "calibrate",
        *(shown_path(e.path) for e in exps),
        options=[("--params", params), ("--drop-na", drop_na)],
    )


def _calibration_payload(result, exps, params, command) -> dict[str, bytes]:
    """calibration.json, the HTML and PDF report and the standalone figures, in memory."""
    from tcamlab.report.calibration_report import calibration_document, figure_files
    from tcamlab.report.html import render_html
    from tcamlab.report.pdf import render_pdf

    doc = calibration_document(result, exps, command=command)
    html = render_html(doc)
    payload = {
        "calibration.json": dumps_json(result.to_dict()).encode(),
        "calibration.html": html.encode(),
        "calibration.pdf": render_pdf(doc),
    }
    payload.update(figure_files(doc, html))
    return payload
