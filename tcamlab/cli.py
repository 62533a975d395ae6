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

from tcamlab import __version__
from tcamlab.kinds import KINDS

app = typer.Typer(
    name="tcamlab",
    help="Lab pipeline for twisted-and-coiled artificial muscles: ingest rig logs, run the "
    "thesis models, validate, identify the spring constant, diagnose the sim-to-real "
    "gap, and write HTML/PDF reports.\n\nExample: tcamlab report",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
validate_app = typer.Typer(
    help="Validate a model against an experiment's runs and write its report.\n\n"
    "Example: tcamlab validate static experiments/static.toml --out reports",
    no_args_is_help=True,
)
benchmark_app = typer.Typer(
    help="Benchmarks of the diagnosis.\n\nExample: tcamlab benchmark diagnose --quick", no_args_is_help=True
)
effects_app = typer.Typer(
    help="The unmodelled-effect library.\n\nExample: tcamlab effects list --kind sensing",
    no_args_is_help=True,
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

Out = Annotated[Path, typer.Option("--out", help="Output folder (created if missing).")]
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
McDraws = Annotated[
    int | None,
    typer.Option("--mc-draws", min=0, help="Monte Carlo draws for the dynamic band (default 1000)."),
]
Experiment = Annotated[Path, typer.Argument(help="Experiment file (TOML).", metavar="EXPERIMENT.toml")]


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
    res = outcome.result
    if as_json:
        _print_json(res.to_dict())
        return
    for q, block in res.metrics[res.primary].items():
        m = block["pooled"]
        typer.echo(
            f"{res.experiment.name}: {res.primary} {q}: RMSE {m['rmse']:.4g}, "
            f"R² {m['r2']:.4g} over {m['n']} samples"
        )
    for note in res.notes:
        typer.echo(f"note: {note}")
    for c in res.checks:
        typer.echo(("pass " if c.passed else "FAIL ") + c.describe())
    typer.echo(f"wrote {outcome.out_dir}")


def _make_validate(kind: str, example: str):
    def command(
        experiment: Experiment,
        out: Out = Path("reports"),
        fmt: str = typer.Option("html,pdf", "--format", help="Report formats: html, pdf or html,pdf."),
        as_json: Json = False,
        drop_na: DropNa = False,
        mc_draws: McDraws = None,
        max_bytes: MaxBytes = None,
    ):
        from tcamlab.pipeline import validate_experiment
        from tcamlab.text import validate_command

        outcome = _run(
            validate_experiment,
            experiment,
            out,
            expected_kind=kind,
            formats=fmt,
            drop_na=drop_na,
            mc_draws=mc_draws,
            max_bytes=max_bytes,
            command=validate_command(kind, experiment, drop_na, mc_draws),
        )
        _print_validation(outcome, as_json)
        if not outcome.passed:
            raise typer.Exit(code=1)

    command.__doc__ = (
        f"Validate the {kind} model against an experiment's runs.\n\n"
        f"Writes OUT/NAME/report.html, report.pdf, metrics.json and "
        f"predictions.csv; exits 1 if a [thresholds] limit is exceeded.\n\n"
        f"Example: {example}"
    )
    return command


for _kind in KINDS:
    validate_app.command(_kind)(_make_validate(_kind, f"tcamlab validate {_kind} experiments/{_kind}.toml"))


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


@app.command("report")
def report(
    experiments: list[Path] | None = typer.Argument(
        None, help="Experiment files (default: all of experiments/).", metavar="[EXPERIMENT.toml]..."
    ),
    out: Out = Path("reports"),
    experiments_dir: Path = typer.Option(
        Path("experiments"), "--experiments", help="Folder searched when no files are given."
    ),
    mc_draws: McDraws = None,
    drop_na: DropNa = False,
    max_bytes: MaxBytes = None,
):
    """Validate every experiment; write each report, index.html and one combined PDF.

    An experiment that cannot be validated is listed in the index with its error
    (exit status 2); the others still build.

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
        typer.echo(f"{e.status:5s} {e.name}" + (f": {e.error}" if e.error else ""))
    typer.echo(f"wrote {outcome.index_path} and {outcome.pdf_path}")
    if any(e.status == "error" for e in outcome.entries):
        raise typer.Exit(code=2)
    if outcome.failed:
        raise typer.Exit(code=1)


# -- fit-spring -------------------------------------------------------------------------


@app.command("fit-spring")
def fit_spring(
    inputs: list[Path] = typer.Argument(
        ..., help="Pull-test CSV logs or sensing experiment files.", metavar="CSV_OR_EXPERIMENT..."
    ),
    intercept: bool = typer.Option(
        False, "--intercept", help="Fit F = S delta + c instead of through the origin."
    ),
    robust: bool = typer.Option(False, "--robust", help="Robust (soft-L1) fit that down-weights outliers."),
    no_branches: bool = typer.Option(
        False, "--no-branches", help="Do not split loading and unloading branches."
    ),
    plot: Path | None = typer.Option(None, "--plot", help="Write the fit and residual plot (.svg or .png)."),
    as_json: Json = False,
    drop_na: DropNa = False,
    max_bytes: MaxBytes = None,
):
    """Identify the spring constant S of F = S delta (thesis section 3.3).

    Least squares through the origin (the thesis's form) or with an intercept;
    standard error, 95% CI and R² per run, per branch and pooled.

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
    )
    if as_json:
        _print_json(rep.to_dict())
        return
    for f in rep.fits + [rep.pooled]:
        lo, hi = f.ci95
        typer.echo(
            f"{f.run:>24s} {f.branch_label:>9s}: S = {f.spring_constant:.5g} N/m "
            f"± {f.stderr:.2g} (95% CI {lo:.5g}..{hi:.5g}), R² {f.r2:.5f}, n {f.n}, "
            f"{f.method}"
        )


# -- simulate ---------------------------------------------------------------------------


@app.command("simulate")
def simulate(
    kind: str = typer.Argument(..., help="static, dynamic, sensing or curvature."),
    experiment: str = typer.Option(
        ...,
        "--experiment",
        help="Template experiment file (sample and rig), or a kind naming the shipped template.",
    ),
    seed: int = typer.Option(..., "--seed", help="Seed of the random generator."),
    out: Out = ...,
    effect: list[str] | None = typer.Option(
        None, "--effect", help="NAME=STRENGTH, strength in multiples of the noise RMS (repeatable)."
    ),
    runs: int | None = typer.Option(None, "--runs", help="Number of runs (default 3)."),
    name: str | None = typer.Option(None, "--name", help="Experiment name (default: the kind)."),
    scatter: list[str] | None = typer.Option(
        None,
        "--scatter",
        help="FIELD=REL: relative sd of a Sample/Rig field between runs, e.g. twists=0.002 (repeatable; default: the rig's small realistic scatter).",
    ),
    noise_scale: float = typer.Option(1.0, "--noise-scale", help="Multiply every instrument noise sd."),
    oven: str = typer.Option(
        "heating",
        "--oven",
        help="Static oven program: heating (thesis, 25->150 degC) or heat-cool (and back down).",
    ),
    parameter_error: float = typer.Option(
        0.0,
        "--parameter-error",
        help="F: draw the true parameters with the stated [rig.uncertainty] sds times F "
        "(kept out of the experiment file; truth file only).",
    ),
    noisy_zero: bool = typer.Option(
        False, "--noisy-zero", help="Zero each run on one noisy reading instead of the averaged tare."
    ),
):
    """Virtual rig: write synthetic run CSVs and an experiment file from the models.

    Realistic measurement chains (noise, ADC quantisation, the thesis's protocols).
    Writes OUT/experiments/, OUT/raw/ and OUT/truth/; effects are hidden from the
    experiment file, the truth goes to truth/NAME.truth.json.

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
    )
    typer.echo(f"wrote {res.experiment_path} and {len(res.run_paths)} runs")


# -- calibrate --------------------------------------------------------------------------


@app.command("calibrate")
def calibrate(
    experiments: Annotated[
        list[Path],
        typer.Argument(help="Experiment files of one sample (TOML).", metavar="EXPERIMENT.toml..."),
    ],
    params: str | None = typer.Option(
        None, "--params", help="Comma-separated parameters to calibrate (default: all of the kinds')."
    ),
    out: Annotated[Path | None, typer.Option("--out", help="Write OUT/NAME/calibration.json.")] = None,
    as_json: Json = False,
    force: bool = typer.Option(False, "--force", help="Overwrite an existing NAME.calibrated.toml."),
):
    """Calibrate the model parameters from the logs, with profile intervals and identifiability.

    Writes NAME.calibrated.toml beside each experiment file.

    Example: tcamlab calibrate experiments/dynamic.toml --out reports --json
    """
    from tcamlab.pipeline import calibrate_experiment

    outcome = _run(calibrate_experiment, experiments, params=params, out_dir=out, force=force)
    doc = outcome.result.to_dict()
    if as_json:
        _print_json(doc)
        return
    for p in doc["parameters"]:
        lo, hi = p["profile_95"]
        shift = "" if p["shift_in_stated_sds"] is None else f" ({p['shift_in_stated_sds']:+.2f} stated sds)"
        typer.echo(f"{p['name']:<24s} {p['value']:.5g} {p['unit']} [{lo:.4g}, {hi:.4g}]{shift}")
    for line in doc["identifiability"]:
        typer.echo("  " + line)
    for f in outcome.files:
        typer.echo(f"wrote {f}")


# -- diagnose ---------------------------------------------------------------------------


@app.command("diagnose")
def diagnose(
    experiment: Experiment,
    effects: str | None = typer.Option(
        None, "--effects", help="Comma-separated candidate effects (default: all of the kind)."
    ),
    out: Annotated[
        Path | None, typer.Option("--out", help="Write OUT/NAME/diagnosis.{html,pdf,json}.")
    ] = None,
    as_json: Json = False,
    seed: int = typer.Option(0, "--seed", help="Seed of the bootstrap."),
):
    """Where the model departs from the logs, which effect explains it, and by how much.

    Example: tcamlab diagnose experiments/static.toml --out reports --json
    """
    from tcamlab.pipeline import diagnose_experiment

    doc = _run(diagnose_experiment, experiment, effects=effects, seed=seed, out_dir=out).result.to_dict()
    if as_json:
        _print_json(doc)
        return
    rec = doc.get("recalibration") or {}
    named = doc.get("effect") or ", ".join(rec.get("named", []))
    typer.echo(f"verdict: {doc['verdict']}" + (f" ({named})" if named else ""))
    typer.echo(f"  {doc['reason']}")
    for name in rec.get("named", []):
        p = rec["parameters"][name]
        shift = p["shift_in_stated_sds"]
        sds = f"{shift:+.1f} stated sds" if shift is not None else f"{p['shift_in_prior_sds']:+.1f} prior sds"
        typer.echo(
            f"  recalibrated {p['symbol']} = {p['value']:.4g} {p['unit']} "
            f"(95 % {p['ci95'][0]:.4g} to {p['ci95'][1]:.4g}; stated {p['stated']:.4g}, {sds})"
        )
    rows = ([doc["combination"]] if doc.get("combination") else []) + doc["ranking"][:5]
    for r in rows:
        typer.echo(
            f"  {r['effect']:<36s} held-out RMSE {r['heldout_rmse_before']:.4g} -> "
            f"{r['heldout_rmse_after']:.4g} ({100 * r['shrinkage']:.0f}% shrinkage)"
        )


# -- benchmark --------------------------------------------------------------------------


def _print_scores(sc: dict) -> None:
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
    if sc.get("median_shrinkage_when_right") is not None:
        typer.echo(f"median held-out shrinkage when right: {100 * sc['median_shrinkage_when_right']:.0f}%")
    if sc["errors"]:
        typer.echo(f"{len(sc['errors'])} cases failed with an error (see benchmark.json)")


@benchmark_app.command("diagnose")
def benchmark_diagnose(
    quick: bool = typer.Option(False, "--quick", help="The CI subset (under 5 minutes)."),
    scheduler: str | None = typer.Option(None, "--scheduler", help="Dask scheduler address."),
    out: Out = Path("reports/benchmark"),
    seeds: int = typer.Option(10, "--seeds", help="Seeds per case (full run; --quick uses at most 2)."),
    workers: int | None = typer.Option(
        None, "--workers", help="Local worker processes (default: all cores)."
    ),
    kind: list[str] | None = typer.Option(None, "--kind", help="Only this rig kind (repeatable)."),
    effect: list[str] | None = typer.Option(None, "--effect", help="Only this effect (repeatable)."),
    lies: bool = typer.Option(
        False,
        "--lies",
        help="Add null cases of a lying rig (parameters 1 stated sd off, noisy zeros), scored apart.",
    ),
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
    )
    _print_scores(res.scores)
    typer.echo(f"wrote {out}")
    if res.scores["errors"]:
        raise typer.Exit(code=2)


# -- effects ----------------------------------------------------------------------------


@effects_app.command("list")
def effects_list(
    kind: str | None = typer.Option(None, "--kind", help="Only this rig kind."),
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
