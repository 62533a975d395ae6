"""Command-line interface: a thin layer over :mod:`tcamlab.pipeline`.

Each command parses its options, calls ONE public pipeline function, prints
the result and sets the exit status; no logic lives here. Options shared by
several commands are declared once below (``Out``, ``Json``...). Library
imports happen inside the commands so ``tcamlab --help`` stays fast.
Exit status: 0 success, 1 a threshold failed, 2 bad input (one-line error).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Annotated

import typer
from typer.core import TyperArgument, TyperCommand, TyperGroup

from tcamlab import __version__
from tcamlab.kinds import KINDS

_KIND_CHOICES = "[" + "|".join(KINDS) + "]"

app = typer.Typer(
    name="tcamlab",
    help="Lab pipeline for twisted-and-coiled artificial muscles: ingest rig logs, run the "
    "thesis models, validate, identify the spring constant, diagnose the sim-to-real "
    "gap, and write HTML/PDF reports.\n\nYour own CSV logs: tcamlab init KIND --csv FILE writes a "
    "starter experiment file whose [columns] table maps your headers and units.\n\nExample: tcamlab report",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    # Plain help: rich markup would swallow "[columns]" and "[rig.uncertainty]" and show <bool>.
    rich_markup_mode=None,
)


class _MetavarArgument(TyperArgument):
    """An argument shown by its metavar alone (Typer appends a placeholder such as ``<list[Path]>``)."""

    def display_type_rich(self, ctx):
        return None if self.metavar else super().display_type_rich(ctx)


class _Command(TyperCommand):
    """A command whose help names its arguments by their metavars (choices, ``EXPERIMENT.toml``)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        for param in self.params:
            if type(param) is TyperArgument:
                param.__class__ = _MetavarArgument  # same fields, only the help line changes


class _ValidateGroup(TyperGroup):
    """``validate EXP.toml`` takes the kind from the file; ``validate KIND EXP.toml`` still works."""

    def parse_args(self, ctx, args):
        first = args[0] if args else ""
        if first and first not in self.commands and (Path(first).suffix or Path(first).exists()):
            args = [_kind_in_file(first), *args]  # a file, not a misspelt kind
        return super().parse_args(ctx, args)


def _kind_in_file(path: str) -> str:
    """The ``kind`` of an experiment file, or the first kind when it cannot be read (loading
    the file then reports what is wrong with it)."""
    import tomllib

    try:
        with open(path, "rb") as fh:  # an experiment file is small: never read a big log whole
            kind = tomllib.loads(fh.read(1 << 20).decode("utf-8-sig")).get("kind")
    except (OSError, ValueError):
        kind = None
    return kind if kind in KINDS else KINDS[0]


validate_app = typer.Typer(
    cls=_ValidateGroup,
    help="Validate a model against an experiment's runs and write its report; the kind is read "
    "from the file (or named first). For your own CSV logs, tcamlab init KIND --csv FILE writes "
    "the experiment file, its [columns] table mapping your headers and units.\n\n"
    "Example: tcamlab validate experiments/static.toml --out reports",
    no_args_is_help=True,
    rich_markup_mode=None,
)
benchmark_app = typer.Typer(
    help="Benchmarks of the diagnosis.\n\nExample: tcamlab benchmark diagnose --quick",
    no_args_is_help=True,
    rich_markup_mode=None,
)
effects_app = typer.Typer(
    help="The unmodelled-effect library.\n\nExample: tcamlab effects list --kind sensing",
    no_args_is_help=True,
    rich_markup_mode=None,
)
app.add_typer(validate_app, name="validate")
app.add_typer(benchmark_app, name="benchmark")
app.add_typer(effects_app, name="effects")


def _max_bytes(value: str) -> int:
    """Parse --max-bytes: a positive integer, optionally with a K/M/G (binary) suffix."""
    text = value.strip()
    factor = 1
    if text[-1:].upper() in ("K", "M", "G"):
        factor = 1024 ** ("KMG".index(text[-1].upper()) + 1)
        text = text[:-1]
    try:
        n = int(text) * factor
    except ValueError:
        n = 0
    if n <= 0:
        raise typer.BadParameter(
            f"expected a positive number of bytes such as 1000000 or 500M, got {value!r}",
            param_hint="'--max-bytes'",
        )
    return n


# -- options shared by several commands, declared once ---------------------------------

Out = Annotated[Path, typer.Option("--out", metavar="DIR", help="Output folder (created if missing).")]
Json = Annotated[bool, typer.Option("--json", help="Print the result as JSON to stdout.")]
DropNa = Annotated[
    bool, typer.Option("--drop-na", help="Drop rows with blank cells (counted in the report).")
]
MaxBytes = Annotated[
    int | None,
    typer.Option(
        "--max-bytes",
        metavar="N",
        parser=_max_bytes,
        help="Refuse CSV logs larger than this many bytes (default 2 GiB); K, M or G suffixes allowed, e.g. 500M.",
    ),
]
Strict = Annotated[
    bool,
    typer.Option(
        "--strict", help="Exit 1 when a sanity check warns (R² < 0, flat prediction, R0 far from rest, ...)."
    ),
]
McDraws = Annotated[
    int | None,
    typer.Option(
        "--mc-draws", min=0, metavar="N", help="Monte Carlo draws for the dynamic band (default 1000)."
    ),
]
EXPERIMENT_HELP = (
    "Experiment file (TOML). For your own CSV logs, tcamlab init KIND --csv FILE writes one whose "
    "[columns] table maps your headers and units."
)
Force = Annotated[
    bool, typer.Option("--force", help="Overwrite this command's existing outputs (default: refuse).")
]
Experiment = Annotated[Path, typer.Argument(help=EXPERIMENT_HELP, metavar="EXPERIMENT.toml")]
Ignore = Annotated[
    list[str] | None,
    typer.Option(
        "--ignore",
        metavar="COLUMN",
        help="Treat this optional logged column as not logged (e.g. load_N: what the self-sensing "
        "estimator does without the load; current_A: a voltage-step test scored on its displacement "
        "alone); repeatable; raw files are not modified.",
    ),
]


def _run(fn, *args, **kwargs):
    """Call the library, turning bad input into a one-line error and exit status 2."""
    from tcamlab.errors import TcamlabError

    try:
        return fn(*args, **kwargs)
    except TcamlabError as exc:
        message, code = exc.one_line(), exc.exit_code
    except FileNotFoundError as exc:
        message, code = f"{exc.filename}: file not found", 2
    except PermissionError as exc:
        message, code = f"{exc.filename}: permission denied", 2
    except OSError as exc:  # e.g. a path that is a folder, a name too long
        where = f"{exc.filename}: " if exc.filename else ""
        message, code = f"{where}{exc.strerror or exc}", 2
    typer.echo(f"error: {message}", err=True)
    raise typer.Exit(code=code)


def _run_shown(as_json: bool, fn, *args, **kwargs):
    """:func:`_run` with the library's progress shown on a terminal (never under --json)."""
    from tcamlab import progress

    with progress.display(progress.wanted(as_json)):
        return _run(fn, *args, **kwargs)


def _print_json(obj) -> None:
    from tcamlab.jsonutil import dumps_json

    typer.echo(dumps_json(obj), nl=False)


def _version_callback(value: bool):
    if value:
        typer.echo(f"tcamlab {__version__}")
        raise typer.Exit()


@app.callback()
def _main(
    version: bool = typer.Option(
        False, "--version", callback=_version_callback, is_eager=True, help="Show the version and exit."
    ),
):
    """tcamlab: validate twisted-and-coiled muscle models against rig logs."""


# -- validate -------------------------------------------------------------------------


def _print_validation(outcome, as_json: bool) -> None:
    from tcamlab.numbers import fmt_r2, unit_label, with_unit

    res = outcome.result
    if as_json:
        _print_json(res.to_dict())
        return
    for q, block in res.metrics[res.primary].items():
        m = block["pooled"]
        typer.echo(
            f"{res.experiment.name}: {res.primary} {q}: RMSE {with_unit(m['rmse'], unit_label(q))}, "
            f"R² {fmt_r2(m['r2'])} over {m['n']} samples" + _bias_text(m, unit_label(q))
        )
        if res.unadjusted is not None:
            u = res.unadjusted[res.primary][q]["pooled"]
            typer.echo(
                f"  whole-run zeros take the mean error away; unadjusted: RMSE "
                f"{with_unit(u['rmse'], unit_label(q))}, bias {with_unit(u['bias'], unit_label(q))}, "
                f"R² {fmt_r2(u['r2'])}"
            )
    for run, zeros in res.zeros_dict()["runs"].items():
        for q, z in zeros.items():
            typer.echo(_zero_line(run, q, z))
    for note in res.notes:
        typer.echo(f"note: {note}")
    for c in res.checks:
        typer.echo(("pass " if c.passed else "FAIL ") + c.describe())
    for w in res.warnings:
        typer.echo(f"WARNING: {w.message}")
    typer.echo(f"status: {res.status}" + (f", {len(res.warnings)} warning(s)" if res.warnings else ""))
    typer.echo(f"wrote {outcome.out_dir}")


def _bias_text(m: dict, unit: str) -> str:
    """``, bias -0.0527 mm (sd 0.0035 mm)``: a pooled bias with its sd from the zeros, or ""."""
    from tcamlab.numbers import fmt, with_unit

    sd = m.get("bias_sd")
    if sd is None or sd != sd or m.get("bias") is None:
        return ""
    bias = 0.0 if abs(m["bias"]) <= 1e-9 * abs(m.get("rmse") or 0.0) else m["bias"]  # rounding
    return f", bias {with_unit(bias, unit)} (sd {fmt(sd, 2)} {unit})"


def _zero_line(run: str, q: str, z: dict) -> str:
    """One estimated zero in lab units: value, standard error and 95% interval."""
    from tcamlab.numbers import bare_name, fmt, unit_label

    unit = unit_label(q)
    if z["value"] is None:
        return f"zero {run} {q}: not estimated"
    text = f"zero {run} {bare_name(q)}: {fmt(z['value'], 3)} {unit}"
    if z["stderr"] is not None:
        lo, hi = z["ci95"]
        text += f" (standard error {fmt(z['stderr'], 2)} {unit}, 95% CI {fmt(lo, 3)} to {fmt(hi, 3)} {unit})"
    if z["source"] == "logged zero":
        return text + f", the logged zero (too few rows at rest; its sd over {z['rows']} row(s))"
    where = f"{z['rows']} rows at rest" if z["source"] == "rest rows" else f"all {z['rows']} rows of the run"
    return text + f", mean residual of {where}; subtracted"


def _make_validate(kind: str, example: str):
    def command(
        experiment: Experiment,
        out: Out = Path("reports"),
        fmt: str = typer.Option(
            "html,pdf",
            "--format",
            metavar="html,pdf[,png,svg]",
            help="Report formats: html, pdf or html,pdf; add png,svg for each figure as a file in figures/.",
        ),
        as_json: Json = False,
        drop_na: DropNa = False,
        mc_draws: McDraws = None,
        max_bytes: MaxBytes = None,
        strict: Strict = False,
        force: Force = False,
        ignore: Ignore = None,
    ):
        import shlex

        from tcamlab.pipeline import validate_experiment
        from tcamlab.text import validate_command

        ignore = list(dict.fromkeys(ignore or ()))
        shown = validate_command(kind, experiment, drop_na, mc_draws)
        shown += "".join(" --ignore " + shlex.quote(c) for c in ignore)
        outcome = _run_shown(
            as_json,
            validate_experiment,
            experiment,
            out,
            expected_kind=kind,
            formats=fmt,
            drop_na=drop_na,
            mc_draws=mc_draws,
            max_bytes=max_bytes,
            command=shown,
            force=force,
            ignore=ignore,
        )
        _print_validation(outcome, as_json)
        if outcome.failed or (strict and outcome.result.warnings):
            raise typer.Exit(code=1)

    command.__doc__ = (
        f"Validate the {kind} model against an experiment's runs.\n\n"
        f"Writes OUT/NAME/report.html, report.pdf, metrics.json and "
        f"predictions.csv (NAME the file's stem, or its path when another file of that stem "
        f"has a report there; an existing report is replaced only with --force); exits 1 if a [thresholds] limit is exceeded (or, with --strict, "
        f"a sanity check warns); without [thresholds] the status is 'no limits set' (exit 0).\n\n"
        f"Example: {example}"
    )
    return command


for _kind in KINDS:
    validate_app.command(_kind, cls=_Command)(
        _make_validate(_kind, f"tcamlab validate {_kind} experiments/{_kind}.toml")
    )


# -- report ---------------------------------------------------------------------------


def _progress_printer():
    """Progress on stderr: one rewritten line on a terminal, one line per experiment in logs."""
    interactive = sys.stderr.isatty() and not os.environ.get("CI")

    def progress(name, i, n):
        if interactive:
            typer.echo(f"\r[{i + 1}/{n}] {name:<40}", err=True, nl=False)
        else:
            typer.echo(f"[{i + 1}/{n}] validating {name}", err=True)

    return progress, interactive


@app.command("report", cls=_Command)
def report(
    experiments: list[Path] | None = typer.Argument(
        None,
        help="Experiment files (default: all of experiments/). " + EXPERIMENT_HELP.split(". ", 1)[1],
        metavar="[EXPERIMENT.toml]...",
    ),
    out: Out = Path("reports"),
    experiments_dir: Path = typer.Option(
        Path("experiments"), "--experiments", metavar="DIR", help="Folder searched when no files are given."
    ),
    mc_draws: McDraws = None,
    drop_na: DropNa = False,
    max_bytes: MaxBytes = None,
    strict: Strict = False,
):
    """Validate every experiment; write each report, index.html and one combined PDF.

    An experiment that cannot be validated is listed in the index with its error
    (exit status 2); the others still build. Exit 1 when a threshold failed, or with
    --strict when a sanity check warns.

    Example: tcamlab report --out reports
    """
    from tcamlab.pipeline import build_reports

    progress, interactive = _progress_printer()
    outcome = _run(
        build_reports,
        experiments or None,
        out,
        experiments_dir=experiments_dir,
        mc_draws=mc_draws,
        drop_na=drop_na,
        max_bytes=max_bytes,
        progress=progress,
    )
    if interactive:
        typer.echo("", err=True)
    for e in outcome.entries:
        typer.echo(f"{e.status_label} {e.name}" + (f": {e.error}" if e.error else ""))
        for w in e.warnings:
            typer.echo(f"  WARNING: {w}")
    typer.echo(f"wrote {outcome.index_path} and {outcome.pdf_path}")
    if any(e.status == "error" for e in outcome.entries):
        raise typer.Exit(code=2)
    if outcome.failed or (strict and any(e.warnings for e in outcome.entries)):
        raise typer.Exit(code=1)


# -- fit-spring -------------------------------------------------------------------------


@app.command("fit-spring", cls=_Command)
def fit_spring(
    inputs: list[Path] = typer.Argument(
        ...,
        help="Pull-test CSV logs (columns mapped with --column) or sensing experiment files (their "
        "[columns] table maps the CSV; tcamlab init sensing --csv FILE writes one).",
        metavar="CSV_OR_EXPERIMENT...",
    ),
    intercept: bool = typer.Option(
        True,
        "--intercept/--origin",
        help="Fit F = S delta + F0 with F0, the load cell's zero, one per run (default), or force "
        "the fit through the origin (F0 = 0, the thesis's form; biased by any tare offset).",
    ),
    robust: bool = typer.Option(False, "--robust", help="Robust (soft-L1) fit that down-weights outliers."),
    no_branches: bool = typer.Option(
        False, "--no-branches", help="Do not split loading and unloading branches."
    ),
    plot: Path | None = typer.Option(
        None,
        "--plot",
        metavar="FILE.png|.svg|.pdf",
        help="Write the fit and residual plot; the extension names the format (.png, .svg, .pdf).",
    ),
    force: bool = typer.Option(False, "--force", help="Overwrite an existing --plot file."),
    as_json: Json = False,
    drop_na: DropNa = False,
    max_bytes: MaxBytes = None,
    column: list[str] | None = typer.Option(
        None,
        "--column",
        metavar="CANON=HEADER[:UNIT[:SCALE]]",
        help="Map a bare CSV's column, e.g. 'force_N=Load [mN]:mN:-1' (repeatable; also "
        "header_row=N, units_row=N); a CSV needs only displacement_mm and force_N.",
    ),
):
    """Identify the spring constant S of F = S delta + F0 (thesis section 3.3).

    F0, the load cell's zero (tare), is fitted per run unless --origin.

    S and F0 with standard error (±) and 95% CI; R² centred or uncentred; per run, branch, pooled.

    Warns when F0 is significant.

    Example: tcamlab fit-spring raw/sensing_run1.csv raw/sensing_run2.csv --json
    """
    from tcamlab.pipeline import fit_spring_files

    rep = _run(
        fit_spring_files,
        inputs,
        intercept=intercept,
        robust=robust,
        by_branch=not no_branches,
        plot_path=plot,
        drop_na=drop_na,
        max_bytes=max_bytes,
        force=force,
        columns=column or None,
    )
    if as_json:
        _print_json(rep.to_dict())
        return
    typer.echo(f"model: {rep.pooled.model}; ± is one standard error, CI the 95% confidence interval")
    for f in rep.fits + [rep.pooled]:
        typer.echo(_spring_line(f))
    for r in rep.pooled.run_intercepts:
        lo, hi = r["intercept_ci95_N"]
        typer.echo(
            f"{'pooled F0 of ' + r['run']:>34s}: {r['intercept_N'] * 1e3:+.3g} mN "
            f"± {r['intercept_stderr_N'] * 1e3:.2g} (95% CI {lo * 1e3:+.3g} to {hi * 1e3:+.3g})"
        )
    for w in rep.warnings:
        typer.echo(f"warning: {w}")


def _spring_line(f) -> str:
    """One spring fit: S and F0 with standard error and 95% CI, labelled R²."""
    lo, hi = f.ci95
    text = (
        f"{f.run:>24s} {f.branch_label:>9s}: S = {f.spring_constant:.5g} N/m "
        f"± {f.stderr:.2g} (95% CI {lo:.5g} to {hi:.5g})"
    )
    if f.through_origin:
        text += ", F0 = 0 (forced)"
    else:
        flo, fhi = f.intercept_ci95
        mean = "mean " if f.run_intercepts else ""
        text += (
            f", {mean}F0 = {f.intercept * 1e3:+.3g} mN ± {f.intercept_stderr * 1e3:.2g} "
            f"(95% CI {flo * 1e3:+.3g} to {fhi * 1e3:+.3g})"
        )
    return text + f", R² ({f.r2_kind}) {f.r2:.5f}, n {f.n}, {f.method}"


# -- init -------------------------------------------------------------------------------


@app.command("init", cls=_Command)
def init(
    kind: str = typer.Argument(..., help="Rig kind of the log.", metavar=_KIND_CHOICES),
    csv: Path = typer.Option(
        ..., "--csv", help="One of your CSV logs (read only, never changed).", metavar="FILE"
    ),
    out: Path | None = typer.Option(
        None,
        "--out",
        metavar="EXPERIMENT.toml",
        help="Experiment file to write (default experiments/<CSV name>.toml); never overwritten.",
    ),
):
    """Write a starter experiment file for your own CSV log.

    Reads the log's header (a title row above it, a units row under it, or no header
    at all), recognises common spellings and units ("Extension (µm)", "Load [mN]",
    "Temp (F)", "R (Ohm)") and writes the [columns] mapping, every [sample] and [rig]
    key of the kind with its definition, unit, how to measure it and a typical value.
    What the log cannot tell is left as "FILL IN" placeholders, which validate refuses,
    naming each key, until they are filled in.

    Example: tcamlab init sensing --csv raw/pull1.csv --out experiments/pull.toml
    """
    from tcamlab.starter import write_starter

    res = _run(write_starter, kind, csv, out)
    for canon, entry in res.mapped.items():
        if canon in ("header_row", "units_row"):
            typer.echo(f"{canon} = {entry}")
            continue
        entry = entry if isinstance(entry, dict) else {"from": entry}
        extra = "".join(f", {k} {entry[k]}" for k in ("scale", "offset") if k in entry)
        typer.echo(f"{canon:<16s} <- {entry.get('from')!r} [{entry.get('unit', '')}{extra}]")
    for line in res.signs:
        typer.echo(f"sign of {line}")
    if res.unused:
        typer.echo("not used: " + ", ".join(res.unused))
    if res.placeholders:
        typer.echo(f"{len(res.placeholders)} values to fill in: " + ", ".join(res.placeholders))
    typer.echo(f"wrote {res.path}; fill it in, then: tcamlab validate {kind} {res.path}")


@app.command("check", cls=_Command)
def check(
    experiment: Experiment,
    rows: int = typer.Option(3, "--rows", min=0, metavar="N", help="First rows of each run shown in SI."),
    drop_na: DropNa = False,
):
    """Dry run: what tcamlab makes of an experiment file, writing nothing.

    Prints each run's column mapping with the file's and the SI units, its first rows
    in SI, every sample and rig value with where it comes from, warnings, and every
    problem at once (the file's and each run's); exits 2 if there is a problem.

    Example: tcamlab check experiments/pull.toml
    """
    from tcamlab.starter import check_experiment

    report = _run(check_experiment, experiment, rows, drop_na=drop_na)
    for line in report.lines():
        typer.echo(line)
    if report.problems:
        raise typer.Exit(code=2)


# -- simulate ---------------------------------------------------------------------------


@app.command("simulate", cls=_Command)
def simulate(
    kind: str = typer.Argument(..., help="Rig kind to simulate.", metavar=_KIND_CHOICES),
    experiment: str = typer.Option(
        ...,
        "--experiment",
        metavar="TEMPLATE.toml|KIND",
        help="Template experiment file (sample and rig), or a kind naming the shipped template.",
    ),
    seed: int = typer.Option(..., "--seed", metavar="N", help="Seed of the random generator."),
    out: Out = ...,
    effect: list[str] | None = typer.Option(
        None,
        "--effect",
        metavar="NAME=STRENGTH",
        help="NAME=STRENGTH, strength in multiples of the noise RMS (repeatable).",
    ),
    runs: int | None = typer.Option(None, "--runs", metavar="N", help="Number of runs (default 3)."),
    name: str | None = typer.Option(
        None, "--name", metavar="NAME", help="Experiment name (default: the template's name)."
    ),
    scatter: list[str] | None = typer.Option(
        None,
        "--scatter",
        metavar="FIELD=REL",
        help="FIELD=REL: relative sd of a Sample/Rig field between runs, e.g. twists=0.002 (repeatable; default: the rig's small realistic scatter).",
    ),
    noise_scale: float = typer.Option(
        1.0, "--noise-scale", metavar="F", help="Multiply every instrument noise sd."
    ),
    oven: str = typer.Option(
        "heating",
        "--oven",
        metavar="[heating|heat-cool]",
        help="Static oven program: heating (thesis, 25->150 degC) or heat-cool (and back down).",
    ),
    parameter_error: float = typer.Option(
        0.0,
        "--parameter-error",
        metavar="F",
        help="F: draw the true parameters with the stated [rig.uncertainty] sds times F "
        "(kept out of the experiment file; truth file only).",
    ),
    noisy_zero: bool = typer.Option(
        False, "--noisy-zero", help="Zero each run on one noisy reading instead of the averaged tare."
    ),
    conditions: int = typer.Option(
        1,
        "--conditions",
        metavar="[1|2]",
        help="2: alternate the runs between the stated condition and a second one "
        "(static: 1.5 x the load, logged as load_N; dynamic: 0.8 x the voltage).",
    ),
    truth: Path | None = typer.Option(
        None,
        "--truth",
        metavar="NAME.truth.json",
        help="Measure the same muscle as an earlier simulation: its effects, true parameters, "
        "zeros and scatter (new noise from --seed); with a protocol file from tcamlab design, "
        "the experiment written lists the runs so far and the new ones.",
    ),
    force: bool = typer.Option(
        False, "--force", help="Replace files that exist (default: refuse and write nothing)."
    ),
):
    """Virtual rig: write synthetic run CSVs and an experiment file from the models.

    Realistic measurement chains (noise, ADC quantisation, the thesis's protocols).
    Writes OUT/experiments/, OUT/raw/ and OUT/truth/; effects are hidden from the
    experiment file, the truth goes to truth/NAME.truth.json. Refuses to replace
    existing files (nothing is written) unless --force.

    Example: tcamlab simulate static --experiment static --seed 1 --out .
    """
    from tcamlab.pipeline import simulate_experiment

    res = _run(
        simulate_experiment,
        kind,
        experiment,
        seed=seed,
        out_dir=out,
        effects=effect,
        runs=runs,
        name=name,
        scatter=scatter,
        noise_scale=noise_scale,
        oven=oven,
        parameter_error=parameter_error,
        noisy_zero=noisy_zero,
        conditions=conditions,
        truth=truth,
        force=force,
    )
    typer.echo(f"wrote {res.experiment_path} and {len(res.run_paths)} runs")


# -- calibrate --------------------------------------------------------------------------


@app.command("calibrate", cls=_Command)
def calibrate(
    experiments: Annotated[
        list[Path],
        typer.Argument(
            help="Experiment files of one sample. " + EXPERIMENT_HELP.split(". ", 1)[1],
            metavar="EXPERIMENT.toml...",
        ),
    ],
    params: str | None = typer.Option(
        None,
        "--params",
        metavar="P,Q,...",
        help="Comma-separated parameters to calibrate (default: all of the kinds').",
    ),
    out: Annotated[
        Path | None,
        typer.Option(
            "--out",
            metavar="DIR",
            help="Write OUT/NAME/calibration.json, the report calibration.html and .pdf, "
            "and its figures as calibration-figN.png and .svg.",
        ),
    ] = None,
    as_json: Json = False,
    force: bool = typer.Option(
        False, "--force", help="Overwrite an existing NAME.calibrated.toml or calibration output."
    ),
    drop_na: DropNa = False,
):
    """Calibrate the model parameters from the logs, with profile intervals and identifiability.

    Writes NAME.calibrated.toml beside each experiment file; with --out, the JSON and the report.

    The report (HTML, PDF) shows the parameters, identifiability, zeros, fits and profiles.

    Nothing is overwritten without --force.

    Example: tcamlab calibrate experiments/dynamic.toml --out reports --json
    """
    from tcamlab.pipeline import calibrate_experiment

    outcome = _run_shown(
        as_json, calibrate_experiment, experiments, params=params, out_dir=out, force=force, drop_na=drop_na
    )
    doc = outcome.result.to_dict()
    if as_json:
        _print_json(doc)
        return
    for p in doc["parameters"]:
        lo, hi = p["profile_95"]
        shift = "" if p["shift_in_stated_sds"] is None else f" ({p['shift_in_stated_sds']:+.2f} stated sds)"
        typer.echo(f"{p['name']:<24s} {p['value']:.5g} {p['unit']} [{lo:.4g}, {hi:.4g}]{shift}")
    for line in [*doc["identifiability"], *doc["notes"]]:
        typer.echo("  " + line)
    for f in outcome.files:
        typer.echo(f"wrote {_relative_if_below(f)}")


def _relative_if_below(path: Path) -> Path:
    """A path as the user would type it: relative to the working folder when below it."""
    try:
        return Path(path).resolve().relative_to(Path.cwd().resolve())
    except ValueError:
        return Path(path)


# -- closed-loop ------------------------------------------------------------------------


@app.command("closed-loop", cls=_Command)
def closed_loop(
    experiment: Experiment,
    out: Annotated[
        Path, typer.Option("--out", metavar="DIR", help="Write OUT/NAME/closed_loop.{html,pdf,json}.")
    ] = Path("reports"),
    seed: int = typer.Option(
        1, "--seed", metavar="N", help="Seed of the virtual rig's noise and of the truth's draw."
    ),
    duration: float = typer.Option(120.0, "--duration", metavar="S", help="Run length [s] (1 kHz)."),
    force: bool = typer.Option(False, "--force", help="Overwrite an existing report."),
):
    """Closed loop on the self-sensed displacement, on the virtual rig (synthetic).

    Open-loop voltage, laser feedback and self-sensing feedback track steps and a sine
    under an unannounced load change; scored against the TRUE displacement, with the
    load unknown to the estimator and with it logged. Parameters from the file (use
    NAME.calibrated.toml from tcamlab calibrate); the plant's are drawn about them.

    Example: tcamlab closed-loop experiments/dynamic.calibrated.toml --out reports
    """
    from tcamlab.estimation.control import closed_loop_experiment

    outcome = _run(closed_loop_experiment, experiment, out, seed=seed, duration=duration, force=force)
    for label, r in outcome.summary["regimes"].items():
        rms = ", ".join(f"{m} {v * 1e3:.3f} mm" for m, v in r["rms_m"].items())
        e = r["estimate"]
        typer.echo(
            f"{label}: tracking RMS {rms}; estimate mean {e['mean'] * 1e3:+.3f} mm, 95% {e['interval95'] * 1e3:.3f} mm"
        )
    for f in outcome.files:
        typer.echo(f"wrote {f}")


# -- diagnose ---------------------------------------------------------------------------


@app.command("diagnose", cls=_Command)
def diagnose(
    experiment: Experiment,
    effects: str | None = typer.Option(
        None,
        "--effects",
        metavar="A,B,...",
        help="Comma-separated candidate effects (default: all of the kind; see tcamlab effects list).",
    ),
    out: Annotated[
        Path | None,
        typer.Option(
            "--out",
            metavar="DIR",
            help="Write OUT/NAME/diagnosis.{html,pdf,json} and each figure as PNG and SVG.",
        ),
    ] = None,
    as_json: Json = False,
    seed: int = typer.Option(0, "--seed", metavar="N", help="Seed of the bootstrap."),
    force: Force = False,
    drop_na: DropNa = False,
    ignore: Ignore = None,
):
    """Where the model departs from the logs, which effect explains it, and by how much.

    With --out, writes OUT/NAME/ (NAME the file's stem, or its path when another file of
    that stem has a diagnosis there); an existing diagnosis is replaced only with --force.

    Example: tcamlab diagnose experiments/static.toml --out reports --json
    """
    from tcamlab.pipeline import diagnose_experiment
    from tcamlab.report.diagnosis_report import diagnosis_lines

    outcome = _run_shown(
        as_json,
        diagnose_experiment,
        experiment,
        effects=effects,
        seed=seed,
        out_dir=out,
        force=force,
        drop_na=drop_na,
        ignore=list(dict.fromkeys(ignore or ())),
    )
    if as_json:
        _print_json(outcome.result.to_dict())
        return
    for line in diagnosis_lines(outcome.result):
        typer.echo(line)
    nxt = outcome.result.next_experiment
    if nxt and nxt.get("best"):
        typer.echo(f"next experiment: {nxt['message']} (tcamlab design writes its protocol file)")
    for f in outcome.files:
        typer.echo(f"wrote {f}")


# -- design -----------------------------------------------------------------------------


@app.command("design", cls=_Command)
def design(
    experiment: Experiment,
    diagnosis: Path | None = typer.Option(
        None, "--diagnosis", metavar="diagnosis.json", help="Use this diagnosis (default: diagnose here)."
    ),
    effects: str | None = typer.Option(
        None, "--effects", metavar="A,B,...", help="Candidate effects of the diagnosis run here."
    ),
    out: Annotated[
        Path | None, typer.Option("--out", metavar="DIR", help="Write OUT/NAME/design.json.")
    ] = None,
    as_json: Json = False,
    seed: int = typer.Option(0, "--seed", metavar="N", help="Seed of the draws and the bootstrap."),
    force: Force = False,
    drop_na: DropNa = False,
):
    """The next protocol that tells apart what the diagnosis could not.

    Scores the kind's protocols by the expected separation of the hypotheses the diagnosis
    left (docs/design.md); writes the best as NAME.next.toml beside the experiment (refused
    if it exists, unless --force) and design.json.

    Example: tcamlab design experiments/static.toml --diagnosis reports/static/diagnosis.json
    """
    from tcamlab.design.text import design_lines
    from tcamlab.pipeline import design_experiment

    if diagnosis is not None:
        _run(_check_diagnosis, experiment, diagnosis)
    outcome = _run_shown(
        as_json,
        design_experiment,
        experiment,
        diagnosis=diagnosis,
        effects=effects,
        out_dir=out,
        force=force,
        seed=seed,
        drop_na=drop_na,
    )
    if as_json:
        _print_json(outcome.result.to_dict())
        return
    from tcamlab.text import shown_path

    for line in design_lines(outcome.result):
        typer.echo(line)
    for f in outcome.files:
        typer.echo(f"wrote {shown_path(f)}")


def _check_diagnosis(experiment, diagnosis) -> None:
    """Refuse a diagnosis.json of another experiment, or of runs changed since."""
    from tcamlab.config import load_experiment
    from tcamlab.design.provenance import check_diagnosis_file

    check_diagnosis_file(load_experiment(experiment), diagnosis)


# -- benchmark --------------------------------------------------------------------------


def _print_loop(c: dict) -> None:
    for x in c["cases"]:
        typer.echo(
            f"loop {x['kind']} {x['family']} {x['truth']}: {x['before']} -> {x['after']} "
            f"after {x['protocol'] or 'no protocol'}"
        )
    d = c["at_least_default"]
    typer.echo(f"designed at least as good as the default with no more runs: {d['k']} of {d['n']}")


def _print_scores(sc: dict) -> None:
    if sc.get("closed_loop"):
        _print_loop(sc["closed_loop"])
    for strength, acc in sorted(sc["accuracy_by_strength"].items(), key=lambda kv: float(kv[0])):
        if acc.get("n"):
            typer.echo(
                f"strength {strength}x: top-1 {acc['top1']:.2f}, top-3 {acc['top3']:.2f} "
                f"over {acc['n']} cases"
            )
    null = sc["null"]
    if null["n"]:
        typer.echo(f"null cases: {null['false_attributions']} false attributions of {null['n']}")
    lying = sc.get("null_miscalibrated")
    if lying:
        typer.echo(
            f"null, miscalibrated: {lying['false_attributions']} false attributions of {lying['n']}, "
            f"{lying.get('right', 0)} none or miscalibrated"
        )
    for fam, f in sc.get("families", {}).items():
        if fam in ("realistic", "off-library"):
            typer.echo(
                f"{fam}: " + ", ".join(f"top-1 {a['top1']:.2f} at {st}x ({a['n']})" for st, a in f.items())
            )
        elif fam == "calibration-only":
            typer.echo(
                f"calibration-only: attributed {f['attributed']} of {f['n']}, miscalibrated naming a moved "
                f"parameter {f['miscalibrated_naming_a_moved_parameter']} of {f['n']}"
            )
        elif fam in ("null-noisy-zero", "null-quiet"):
            what = "noisy zeros" if fam == "null-noisy-zero" else "noisy zeros, quiet instruments"
            typer.echo(
                f"null, {what}: {f['false_attributions']} false attributions, {f['none']} none, of {f['n']}"
            )
    if sc.get("median_shrinkage_when_right") is not None:
        typer.echo(f"median held-out shrinkage when right: {100 * sc['median_shrinkage_when_right']:.0f}%")
    if sc["errors"]:
        typer.echo(f"{len(sc['errors'])} cases failed with an error (see benchmark.json)")


@benchmark_app.command("diagnose", cls=_Command)
def benchmark_diagnose(
    quick: bool = typer.Option(False, "--quick", help="The CI subset (under 5 minutes)."),
    scheduler: str | None = typer.Option(
        None, "--scheduler", metavar="ADDRESS", help="Dask scheduler address (default: local processes)."
    ),
    out: Out = Path("reports/benchmark"),
    seeds: int = typer.Option(
        10, "--seeds", metavar="N", help="Seeds per case (full run; --quick uses at most 2)."
    ),
    workers: int | None = typer.Option(
        None, "--workers", metavar="N", help="Local worker processes (default: all cores)."
    ),
    kind: list[str] | None = typer.Option(
        None, "--kind", metavar=_KIND_CHOICES, help="Only this rig kind (repeatable; default: all)."
    ),
    effect: list[str] | None = typer.Option(
        None, "--effect", metavar="NAME", help="Only this effect (repeatable; see tcamlab effects list)."
    ),
    lies: bool = typer.Option(
        False,
        "--lies",
        help="Add null cases of a lying rig (parameters 1 stated sd off, noisy zeros), scored apart.",
    ),
    family: list[str] | None = typer.Option(
        None,
        "--family",
        metavar="FAMILY",
        help="Only this family (repeatable): effect-only, null, calibration-only, realistic, "
        "off-library, null-noisy-zero, null-quiet. Default: all.",
    ),
    conditions: int = typer.Option(
        1,
        "--conditions",
        metavar="[1|2]",
        help="2: two-condition experiments (static: a second load; dynamic: a second voltage); "
        "only those kinds run.",
    ),
    template: list[Path] | None = typer.Option(
        None,
        "--template",
        metavar="FILE",
        help="Benchmark this experiment file's sample and rig instead of its kind's bundled "
        "template (repeatable, one per kind; default kinds: theirs).",
    ),
    closed_loop: bool = typer.Option(
        False,
        "--closed-loop",
        help="Close the loop on each case: design the next protocol, run it on the virtual rig "
        "(same muscle, new noise) and diagnose again; scores before and after (kinds with a "
        "protocol menu; --quick: one case per family and kind).",
    ),
    force: Force = False,
):
    """Withheld-effect benchmark of the diagnosis: attribution accuracy and shrinkage.

    Simulates every effect at 1x, 3x and 10x the noise RMS (10 seeds), null cases and
    pairs; diagnoses each with the effect withheld; writes benchmark.json, .md, .html, .pdf.

    Example: tcamlab benchmark diagnose --quick --out reports/benchmark
    """
    from tcamlab.pipeline import benchmark_diagnosis

    res = _run(
        benchmark_diagnosis,
        out,
        kinds=kind,
        effects=effect,
        quick=quick,
        scheduler=scheduler,
        workers=workers,
        seeds=seeds,
        lies=lies,
        families=family or None,
        conditions=conditions,
        templates=template or None,
        closed_loop=closed_loop,
        force=force,
    )
    _print_benchmark(res, out)


def _print_benchmark(res, out) -> None:
    """The benchmark's scores, its full-run estimate and where it wrote; exit 2 on failed cases."""
    _print_scores(res.scores)
    plan = res.settings.get("full_run_estimate") or {}
    if plan:
        typer.echo(
            f"full run of every family, estimated: {plan['total_seconds'] / 60:.0f} min on {plan['cores']} cores"
        )
    typer.echo(f"wrote {out}")
    if res.scores["errors"]:
        raise typer.Exit(code=2)


# -- effects ----------------------------------------------------------------------------


@effects_app.command("list", cls=_Command)
def effects_list(
    kind: str | None = typer.Option(None, "--kind", help="Only this rig kind.", metavar=_KIND_CHOICES),
    as_json: Json = False,
):
    """List the unmodelled effects with their parameters and physical causes.

    Example: tcamlab effects list --kind static
    """
    from tcamlab.pipeline import list_effects

    listing = _run(list_effects, kind)
    if as_json:
        _print_json(listing.to_records())
        return
    for e in listing.effects:
        params = ", ".join(f"{p.field} [{p.unit}]" for p in e.params)
        typer.echo(f"{e.kind:<10s} {e.name:<28s} {params}\n{'':11s}{e.cause}")


def main() -> None:
    """Console-script entry point."""
    app(prog_name="tcamlab")


if __name__ == "__main__":
    main()


# the click command behind the Typer app, for the generated CLI reference (docs/cli.md)
click_command = typer.main.get_command(app)
