"""Text shared by the commands: did-you-mean suggestions and recorded command lines.

Command lines written into reports, experiment files and truth files are
built here only, from parsed options (never ``sys.argv``), so that the same
options always give the same bytes.
"""

from __future__ import annotations

import difflib
import os
import shlex
from collections.abc import Iterable, Mapping
from pathlib import Path

__all__ = [
    "clipped",
    "did_you_mean",
    "close_matches",
    "shown_path",
    "command_line",
    "validate_command",
    "simulate_command",
    "public_command",
    "HIDDEN_SIMULATE_OPTIONS",
]


def close_matches(word: str, choices: Iterable[str], n: int = 1) -> list[str]:
    """Choices close to word; a case-insensitive second try catches 'Force' for 'force'."""
    choices = list(choices)
    matches = difflib.get_close_matches(word, choices, n=n, cutoff=0.6)
    if not matches:
        lowered = {c.lower(): c for c in choices}
        matches = [
            lowered[m] for m in difflib.get_close_matches(word.lower(), list(lowered), n=n, cutoff=0.5)
        ]
    return matches


def did_you_mean(word: str, choices: Iterable[str], n: int = 1) -> str:
    """``"; did you mean 'x'?"`` for an error message, or ``""`` when nothing is close."""
    matches = close_matches(word, choices, n)
    return "; did you mean " + " or ".join(repr(m) for m in matches) + "?" if matches else ""


def clipped(text: str, width: int = 80) -> str:
    """``text`` cut to at most ``width`` characters at a word boundary, "..." marking the cut."""
    import textwrap

    return textwrap.shorten(str(text), width=width, placeholder=" ...")


def shown_path(p) -> str:
    """A path as shown in a report: relative to the working directory when below it,
    else elided to its name, so reports carry no absolute paths."""
    p = Path(os.path.normpath(p))  # "edge/../raw/run.csv" is below the working directory too
    if not p.is_absolute():
        return p.as_posix()
    try:
        return p.relative_to(Path.cwd()).as_posix()
    except ValueError:
        return ".../" + p.name


def _number(x) -> str:
    if isinstance(x, (list, tuple)):  # an effect given by its parameter values
        return ",".join(_number(v) for v in x)
    x = float(x)
    return str(int(x)) if x.is_integer() else repr(x)


def command_line(*words, options: Iterable[tuple[str, object]] = ()) -> str:
    """``tcamlab WORDS... --flag value...``, shell-quoted; an option whose value is
    None or False is left out, True gives the bare flag."""
    parts = ["tcamlab", *map(str, words)]
    for flag, value in options:
        if value is None or value is False:
            continue
        parts += [flag] if value is True else [flag, str(value)]
    return shlex.join(parts)


def validate_command(kind: str, experiment, drop_na: bool = False, mc_draws: int | None = None) -> str:
    """The validate command line shown in a report's provenance.

    Only the options that change the report's content, with the experiment
    path made relative, so the report is byte-identical wherever the lab
    folder lives and wherever the report is written (--out, --format, --json,
    --max-bytes do not change a byte of it).
    """
    return command_line(
        "validate", kind, shown_path(experiment), options=[("--drop-na", drop_na), ("--mc-draws", mc_draws)]
    )


def simulate_command(
    kind: str,
    template,
    seed: int,
    out_dir,
    *,
    runs: int | None = None,
    name: str | None = None,
    noise_scale: float = 1.0,
    oven: str = "heating",
    scatter: Mapping[str, float] | None = None,
    effects: Mapping[str, float] | None = None,
    parameter_error: float = 0.0,
    noisy_zero: bool = False,
    conditions: int = 1,
    truth=None,
) -> str:
    """The simulate command line recorded in experiment and truth files (defaults left out)."""
    options = [
        ("--experiment", template),
        ("--seed", seed),
        ("--out", out_dir),
        ("--runs", runs),
        ("--name", name),
        ("--noise-scale", None if noise_scale == 1.0 else repr(float(noise_scale))),
        ("--oven", None if oven == "heating" else oven),
        ("--conditions", None if conditions == 1 else int(conditions)),
        ("--parameter-error", _number(parameter_error) if parameter_error else None),
        ("--noisy-zero", bool(noisy_zero)),
        ("--truth", truth),
    ]
    options += [("--scatter", f"{k}={_number(v)}") for k, v in (scatter or {}).items()]
    options += [("--effect", f"{k}={_number(v)}") for k, v in (effects or {}).items()]
    return command_line("simulate", kind, options=options)


HIDDEN_SIMULATE_OPTIONS = {"--effect": 1, "-e": 1, "--parameter-error": 1, "--noisy-zero": 0, "--truth": 1}
"""simulate options the experiment file must not show (option -> values it takes): the
effects and the rig's lies (true parameters off the stated ones, noisy zeros)."""


def public_command(command: str) -> str:
    """A simulate command line without its hidden options (:data:`HIDDEN_SIMULATE_OPTIONS`),
    for the experiment file, which must not reveal the effects or the rig's lies; the
    truth file keeps them."""
    try:
        parts = shlex.split(command)
    except ValueError:
        return "tcamlab simulate"
    out, skip = [], 0
    for p in parts:
        if skip:
            skip -= 1
            continue
        if p in HIDDEN_SIMULATE_OPTIONS:
            skip = HIDDEN_SIMULATE_OPTIONS[p]
            continue
        if p.split("=", 1)[0] in HIDDEN_SIMULATE_OPTIONS and "=" in p:
            continue
        out.append(p)
    return shlex.join(out)
