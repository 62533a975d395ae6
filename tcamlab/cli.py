"""Command-line interface: parses arguments, calls :mod:`tcamlab.pipeline`, prints.

No logic lives here beyond argument parsing, progress display and exit codes.
Library imports happen inside the commands so ``tcamlab --help`` stays fast.
Exit status: 0 success, 1 a threshold failed, 2 bad input (one-line error).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import typer

from tcamlab import __version__

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

KINDS = ("static", "dynamic", "sensing", "curvature")


def _fail(exc) -> None:
    """Print tcamlab's one-line error and exit with its status."""
    typer.echo(f"error: {exc.one_line()}", err=True)
    raise typer.Exit(code=exc.exit_code)


def _run(fn):
    """Call fn(), turning tcamlab errors into one-line messages and exit codes."""
    from tcamlab.errors import TcamlabError

    try:
        return fn()
    except TcamlabError as exc:
        _fail(exc)
    except FileNotFoundError as exc:
        typer.echo(f"error: {exc.filename}: file not found", err=True)
        raise typer.Exit(code=2) from None
    except PermissionError as exc:
        typer.echo(f"error: {exc.filename}: permission denied", err=True)
        raise typer.Exit(code=2) from None
    except OSError as exc:  # e.g. a path that is a folder, a name too long
        where = f"{exc.filename}: " if exc.filename else ""
        typer.echo(f"error: {where}{exc.strerror or exc}", err=True)
        raise typer.Exit(code=2) from None


def _shown_path(p: Path) -> str:
    """A path as shown in a report: relative to the working directory when below it,
    else elided to its name, so reports carry no absolute paths."""
    if not p.is_absolute():
        return p.as_posix()
    try:
        return p.relative_to(Path.cwd()).as_posix()
    except ValueError:
        return ".../" + p.name


def _validate_command(kind: str, experiment: Path, drop_na: bool, mc_draws: int | None) -> str:
    """The validate command line as shown in the report's provenance.

    Rebuilt from the parsed options (not sys.argv), with the experiment path
    made relative and only the options that change the report's content, so
    the report is byte-identical wherever the lab folder lives and wherever
    the report is written (--out, --format, --json, --max-bytes do not
    change a byte of it).
    """
    parts = ["tcamlab", "validate", kind, _shown_path(experiment)]
    if drop_na:
        parts.append("--drop-na")
    if mc_draws is not None:
        parts += ["--mc-draws", str(mc_draws)]
    return " ".join(parts)


_MAX_BYTES_HELP = (
    "Refuse CSV logs larger than this many bytes (default 2 GiB); K, M or G suffixes allowed, e.g. 500M."
)


def _max_bytes(value: str | None) -> int | None:
    """Parse --max-bytes: a positive integer, optionally with a K/M/G (binary) suffix."""
    if value is None:
        return None
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


def _command_line() -> str:
    return "tcamlab " + " ".join(sys.argv[1:]) if sys.argv else "tcamlab"


def _print_json(obj) -> None:
    from tcamlab.pipeline import dumps_json

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


def _validate(
    kind: str,
    experiment: Path,
    out: Path,
    fmt: str,
    as_json: bool,
    drop_na: bool,
    mc_draws: int | None,
    max_bytes: int | None,
) -> None:
    from tcamlab.pipeline import validate_experiment

    command = _validate_command(kind, experiment, drop_na, mc_draws)
    outcome = _run(
        lambda: validate_experiment(
            experiment,
            out,
            expected_kind=kind,
            formats=fmt,
            drop_na=drop_na,
            mc_draws=mc_draws,
            max_bytes=max_bytes,
            command=command,
        )
    )
    res = outcome.result
    if as_json:
        _print_json(res.to_dict())
    else:
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
    if not res.passed:
        raise typer.Exit(code=1)


def _make_validate(kind: str, example: str):
    def command(
        experiment: Path = typer.Argument(..., help="Experiment file (TOML).", metavar="EXPERIMENT.toml"),
        out: Path = typer.Option(Path("reports"), "--out", help="Parent folder of the report."),
        fmt: str = typer.Option("html,pdf", "--format", help="Report formats: html, pdf or html,pdf."),
        as_json: bool = typer.Option(False, "--json", help="Print metrics.json to stdout."),
        drop_na: bool = typer.Option(
            False, "--drop-na", help="Drop rows with blank cells (counted in the report)."
        ),
        mc_draws: int | None = typer.Option(
            None, "--mc-draws", min=0, help="Monte Carlo draws for the dynamic band (default 1000)."
        ),
        max_bytes: str | None = typer.Option(None, "--max-bytes", metavar="N", help=_MAX_BYTES_HELP),
    ):
        _validate(kind, experiment, out, fmt, as_json, drop_na, mc_draws, _max_bytes(max_bytes))

    command.__doc__ = (
        f"Validate the {kind} model against an experiment's runs.\n\n"
        f"Writes OUT/NAME/report.html, report.pdf, metrics.json and "
        f"predictions.csv; exits 1 if a [thresholds] limit is exceeded.\n\n"
        f"Example: {example}"
    )
    return command


for _kind, _ex in (
    ("static", "tcamlab validate static experiments/static.toml"),
    ("dynamic", "tcamlab validate dynamic experiments/dynamic.toml --format html"),
    ("sensing", "tcamlab validate sensing experiments/sensing.toml --json"),
    ("curvature", "tcamlab validate curvature experiments/curvature.toml --out reports"),
):
    validate_app.command(_kind)(_make_validate(_kind, _ex))


# -- report ---------------------------------------------------------------------------


@app.command("report")
def report(
    experiments: list[Path] | None = typer.Argument(
        None, help="Experiment files (default: all of experiments/).", metavar="[EXPERIMENT.toml]..."
    ),
    out: Path = typer.Option(Path("reports"), "--out", help="Output folder."),
    experiments_dir: Path = typer.Option(
        Path("experiments"), "--experiments", help="Folder searched when no files are given."
    ),
    mc_draws: int | None = typer.Option(
        None, "--mc-draws", min=0, help="Monte Carlo draws for dynamic bands."
    ),
    drop_na: bool = typer.Option(
        False, "--drop-na", help="Drop rows with blank cells (counted in each report)."
    ),
    max_bytes: str | None = typer.Option(None, "--max-bytes", metavar="N", help=_MAX_BYTES_HELP),
):
    """Validate every experiment; write each report, index.html and one combined PDF.

    An experiment that cannot be validated is listed in the index with its error
    (exit status 2); the others still build.

    Example: tcamlab report --out reports
    """
    limit = _max_bytes(max_bytes)
    from tcamlab.pipeline import build_reports

    interactive = sys.stderr.isatty() and not os.environ.get("CI")

    def progress(name, i, n):
        if interactive:
            typer.echo(f"\r[{i + 1}/{n}] {name:<40}", err=True, nl=False)
        else:
            typer.echo(f"[{i + 1}/{n}] validating {name}", err=True)

    outcome = _run(
        lambda: build_reports(
            experiments or None,
            out,
            experiments_dir=experiments_dir,
            mc_draws=mc_draws,
            drop_na=drop_na,
            max_bytes=limit,
            progress=progress,
        )
    )
    if interactive:
        typer.echo("", err=True)
    for e in outcome.entries:
        line = f"{e.status:5s} {e.name}"
        if e.error:
            line += f": {e.error}"
        typer.echo(line)
    typer.echo(f"wrote {outcome.index_path} and {outcome.pdf_path}")
    errors = [e for e in outcome.entries if e.status == "error"]
    if errors:
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
    as_json: bool = typer.Option(False, "--json", help="Print the result as JSON."),
    drop_na: bool = typer.Option(False, "--drop-na", help="Drop rows with blank cells."),
    max_bytes: str | None = typer.Option(None, "--max-bytes", metavar="N", help=_MAX_BYTES_HELP),
):
    """Identify the spring constant S of F = S delta (thesis section 3.3).

    Least squares through the origin (the thesis's form) or with an intercept;
    standard error, 95% CI and R² per run, per branch and pooled.

    Example: tcamlab fit-spring raw/sensing_run1.csv raw/sensing_run2.csv --json
    """
    from tcamlab.pipeline import fit_spring_files

    limit = _max_bytes(max_bytes)
    rep = _run(
        lambda: fit_spring_files(
            inputs,
            intercept=intercept,
            robust=robust,
            by_branch=not no_branches,
            plot_path=plot,
            drop_na=drop_na,
            max_bytes=limit,
        )
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


def _parse_effects(items: list[str]) -> dict:
    from tcamlab.errors import ConfigError

    out = {}
    for item in items or []:
        name, sep, value = item.partition("=")
        try:
            out[name.strip()] = float(value)
        except ValueError:
            raise ConfigError(
                f"--effect {item!r}: expected NAME=STRENGTH",
                hint="e.g. --effect glass-transition=3 (3x the noise RMS)",
            ) from None
        if not sep:
            raise ConfigError(f"--effect {item!r}: expected NAME=STRENGTH")
    return out


def _parse_scatter(items: list[str] | None) -> dict | None:
    from tcamlab.errors import ConfigError

    if not items:
        return None
    out = {}
    for item in items:
        field, sep, value = item.partition("=")
        try:
            out[field.strip()] = float(value)
        except ValueError:
            raise ConfigError(
                f"--scatter {item!r}: expected FIELD=REL",
                hint="e.g. --scatter twists=0.002 (0.2% between runs)",
            ) from None
        if not sep:
            raise ConfigError(f"--scatter {item!r}: expected FIELD=REL")
    return out


@app.command("simulate")
def simulate(
    kind: str = typer.Argument(..., help="static, dynamic, sensing or curvature."),
    experiment: Path = typer.Option(..., "--experiment", help="Template experiment file (sample and rig)."),
    seed: int = typer.Option(..., "--seed", help="Seed of the random generator."),
    out: Path = typer.Option(..., "--out", help="Folder receiving experiments/, raw/ and truth/."),
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
):
    """Virtual rig: write synthetic run CSVs and an experiment file from the models.

    Realistic measurement chains (noise, ADC quantisation, the thesis's protocols).
    Effects are hidden from the experiment file; the truth goes to truth/NAME.truth.json.

    Example: tcamlab simulate static --experiment experiments/templates/static.toml --seed 1 --out .
    """
    from tcamlab.errors import ConfigError

    if kind not in KINDS:
        _fail(ConfigError(f"unknown kind {kind!r}", hint="one of " + ", ".join(KINDS)))

    def go():
        from tcamlab import rig

        return rig.simulate(
            kind,
            experiment,
            seed=seed,
            out_dir=out,
            effects=_parse_effects(effect),
            n_runs=runs,
            name=name,
            scatter=_parse_scatter(scatter),
            noise_scale=noise_scale,
            oven=oven,
            command=command,
        )

    command = f"tcamlab simulate {kind} --experiment {experiment} --seed {seed} --out {out}"
    for flag, value, default in (
        ("--runs", runs, None),
        ("--name", name, None),
        ("--noise-scale", noise_scale, 1.0),
        ("--oven", oven, "heating"),
    ):
        if value != default:
            command += f" {flag} {value}"
    for item in scatter or []:
        command += f" --scatter {item}"
    for item in effect or []:
        command += f" --effect {item}"

    res = _run(go)
    typer.echo(f"wrote {res.experiment_path} and {len(res.run_paths)} runs")


# -- diagnose ---------------------------------------------------------------------------


@app.command("diagnose")
def diagnose(
    experiment: Path = typer.Argument(..., help="Experiment file (TOML).", metavar="EXPERIMENT.toml"),
    effects: str | None = typer.Option(
        None, "--effects", help="Comma-separated candidate effects (default: all of the kind)."
    ),
    out: Path | None = typer.Option(None, "--out", help="Write OUT/NAME/diagnosis.{html,pdf,json}."),
    as_json: bool = typer.Option(False, "--json", help="Print the diagnosis as JSON."),
    seed: int = typer.Option(0, "--seed", help="Seed of the bootstrap."),
):
    """Where the model departs from the logs, which effect explains it, and by how much.

    Example: tcamlab diagnose experiments/static.toml --out reports --json
    """

    def go():
        from tcamlab.config import load_experiment
        from tcamlab.diagnosis import diagnose as run_diagnosis

        exp = load_experiment(experiment)
        names = [e.strip() for e in effects.split(",")] if effects else None
        result = run_diagnosis(exp, effects=names, seed=seed)
        if out is not None:
            from tcamlab.pipeline import write_diagnosis

            write_diagnosis(result, exp, out)
        return result

    result = _run(go)
    doc = result.to_dict()
    if as_json:
        _print_json(doc)
        return
    typer.echo(f"verdict: {doc['verdict']}" + (f" ({doc['effect']})" if doc.get("effect") else ""))
    typer.echo(f"  {doc['reason']}")
    rows = ([doc["combination"]] if doc.get("combination") else []) + doc["ranking"][:5]
    for r in rows:
        typer.echo(
            f"  {r['effect']:<36s} held-out RMSE {r['heldout_rmse_before']:.4g} -> "
            f"{r['heldout_rmse_after']:.4g} ({100 * r['shrinkage']:.0f}% shrinkage)"
        )


# -- benchmark --------------------------------------------------------------------------


@benchmark_app.command("diagnose")
def benchmark_diagnose(
    quick: bool = typer.Option(False, "--quick", help="The CI subset (under 5 minutes)."),
    scheduler: str | None = typer.Option(None, "--scheduler", help="Dask scheduler address."),
    out: Path = typer.Option(Path("reports/benchmark"), "--out", help="Output folder."),
    seeds: int = typer.Option(10, "--seeds", help="Seeds per case (full run; --quick uses at most 2)."),
    workers: int | None = typer.Option(
        None, "--workers", help="Local worker processes (default: all cores)."
    ),
    kind: list[str] | None = typer.Option(None, "--kind", help="Only this rig kind (repeatable)."),
    effect: list[str] | None = typer.Option(None, "--effect", help="Only this effect (repeatable)."),
):
    """Withheld-effect benchmark of the diagnosis: attribution accuracy and shrinkage.

    Simulates every effect at 1x, 3x and 10x the noise RMS (10 seeds), null cases and
    pairs; diagnoses each with the effect withheld; writes benchmark.json, .md, .html, .pdf.

    Example: tcamlab benchmark diagnose --quick --out reports/benchmark
    """
    from tcamlab.errors import ConfigError

    kinds = tuple(kind) if kind else KINDS
    bad = [k for k in kinds if k not in KINDS]
    if bad:
        _fail(ConfigError(f"--kind {bad[0]!r}: unknown kind", hint="one of " + ", ".join(KINDS)))

    def go():
        from tcamlab.benchmark import run_benchmark

        return run_benchmark(
            out,
            quick=quick,
            scheduler=scheduler,
            workers=workers,
            seeds=seeds,
            kinds=kinds,
            effects=list(effect) if effect else None,
        )

    res = _run(go)
    sc = res.scores
    for strength, acc in sorted(sc["accuracy_by_strength"].items(), key=lambda kv: float(kv[0])):
        if acc.get("n"):
            typer.echo(
                f"strength {strength}x: top-1 {acc['top1']:.2f}, top-3 {acc['top3']:.2f} "
                f"over {acc['n']} cases"
            )
    null = sc["null"]
    if null["n"]:
        typer.echo(f"null cases: {null['false_attributions']} false attributions of {null['n']}")
    if sc.get("median_shrinkage_when_right") is not None:
        typer.echo(f"median held-out shrinkage when right: {100 * sc['median_shrinkage_when_right']:.0f}%")
    if sc["errors"]:
        typer.echo(f"{len(sc['errors'])} cases failed with an error (see benchmark.json)")
    typer.echo(f"wrote {out}")
    if sc["errors"]:
        raise typer.Exit(code=2)


# -- effects ----------------------------------------------------------------------------


@effects_app.command("list")
def effects_list(
    kind: str | None = typer.Option(None, "--kind", help="Only this rig kind."),
    as_json: bool = typer.Option(False, "--json", help="Print as JSON."),
):
    """List the unmodelled effects with their parameters and physical causes.

    Example: tcamlab effects list --kind static
    """
    from tcamlab.effects import EFFECTS

    rows = [e for e in EFFECTS.values() if kind is None or e.kind == kind]
    if as_json:
        _print_json(
            [
                {
                    "kind": e.kind,
                    "name": e.name,
                    "cause": e.cause,
                    "source": e.source,
                    "parameters": [{"name": p.field, "unit": p.unit} for p in e.params],
                }
                for e in rows
            ]
        )
        return
    for e in rows:
        params = ", ".join(f"{p.field} [{p.unit}]" for p in e.params)
        typer.echo(f"{e.kind:<10s} {e.name:<28s} {params}\n{'':11s}{e.cause}")


def main() -> None:
    """Console-script entry point."""
    app(prog_name="tcamlab")


if __name__ == "__main__":
    main()
