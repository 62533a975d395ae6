"""The design's result as a few lines of text (the CLI's table)."""

from __future__ import annotations

import math

from tcamlab.kinds import get_kind
from tcamlab.units import display

__all__ = ["design_lines"]


def _diff(c, kind: str) -> str:
    """Largest predicted difference of the hardest pair, in display units (a channel the
    protocol adds beyond the kind's outputs to 3 significant figures)."""
    if not c.pairs:
        return "-"
    pair = min(c.pairs, key=c.pairs.get)
    outputs = get_kind(kind).outputs
    parts = []
    for q, v in c.max_difference[pair].items():
        unit, fac = display(q)
        parts.append(f"{q} {v * fac:{'.3f' if q in outputs else '.3g'}} {unit}")
    return ", ".join(parts)


def _per_hour(x: float) -> str:
    return f"{x:7.2f}" if abs(x) < 1e4 else f"{x:7.3g}"


def _num(x: float) -> str:
    return "inf" if math.isinf(x) else (f"{x:.3g}" if abs(x) < 100 else f"{x:.0f}")


def _at_fit(c, out_of_reach) -> str:
    """The weakest effect's Wald statistic at its fit after the protocol, among the effects
    within the menu's reach ("-": none)."""
    vals = [v for n, v in c.at_fit.items() if n not in out_of_reach]
    if not vals:
        return "-"
    return "nan" if any(math.isnan(v) for v in vals) else _num(min(vals))


def design_lines(result) -> list[str]:
    """Headline, hypotheses, then one line per protocol (best first)."""
    lines = [f"{result.experiment}: {result.message}"]
    if not result.candidates:
        return lines
    lines.append("hypotheses: " + "; ".join(_hypothesis(h) for h in result.hypotheses))
    if result.status == "clear":
        return lines + _precision_lines(result)
    head = (
        f"{'protocol':42s} {'J':>8s} {'beyond':>8s} {'at fit':>8s} {'D rows':>8s} {'runs':>4s} {'min':>6s} "
        f"{'per h':>7s}  max difference"
    )
    lines += [head, "-" * len(head)]
    for c in result.candidates:
        mark = "*" if result.best is not None and c.name == result.best.name else " "
        if not c.feasible:
            lines.append(f"{mark}{c.name:41s} {_bounds(c):>8s}  {c.limit}")
            continue
        lines.append(
            f"{mark}{c.name:41s} {_num(c.separation_refit):>8s} {_num(c.beyond_repeat):>8s} {_at_fit(c, result.out_of_reach):>8s} "
            f"{_num(c.separation):>8s} "
            f"{c.runs:4d} {c.minutes:6.0f} {_per_hour(c.per_hour)}  {_diff(c, result.kind)}"
        )
    return lines


def _bounds(c) -> str:
    """Why a protocol is not ranked: out of bounds, or not scored where the sample has been
    through it (the model could not predict it, which says nothing of the sample)."""
    return "not scored" if getattr(c, "survived", False) else "out of bounds"


def _hypothesis(h: dict) -> str:
    parts = []
    for name, p in h["parameters"].items():
        lo, hi = (p.get("ci95") or [None, None])[:2]
        if p.get("value") is None:
            continue
        ci = f" ({lo:.3g} to {hi:.3g})" if lo is not None and hi is not None else ""
        parts.append(f"{name} {p['value']:.3g}{ci} {p.get('unit') or ''}".rstrip())
    return f"{h['name']}: " + ", ".join(parts)


def _precision_lines(result) -> list[str]:
    """One line per protocol of a clear diagnosis: information gain and the sds it leaves."""
    head = f"{'protocol':30s} {'gain':>6s} {'runs':>4s} {'min':>6s} {'per h':>6s}  sd after / before"
    out = [head, "-" * len(head)]
    for c in result.candidates:
        mark = "*" if result.best is not None and c.name == result.best.name else " "
        if not c.feasible:
            out.append(f"{mark}{c.name:29s} {_bounds(c):>13s}  {c.limit}")
            continue
        ratios = ", ".join(f"{n} {r:.2f}" for n, r in c.sd_ratio.items())
        out.append(
            f"{mark}{c.name:29s} {c.information_gain:6.2f} {c.runs:4d} {c.minutes:6.0f} {c.per_hour:6.2f}  {ratios}"
        )
    return out
