"""Coverage of `tcamlab calibrate`'s 95 % intervals on a virtual rig that lies like a lab.

Run: python bench/bench_calibration_coverage.py [--kinds static,dynamic] [--cases 100]
     [--seed 0] [--jobs 2] [--priors stated|default] [--out DIR [--force | --resume]] [--quick]
     python bench/bench_calibration_coverage.py --from-cases DIR/cases.jsonl  # re-summarise

``--quick`` (the CI smoke run) calibrates 2 cases per kind; the table is
printed, nothing is asserted on coverage or time (a fit that raises is
counted as failed; a truth the rig cannot simulate is skipped).

Each case is synthetic: the virtual rig (:func:`tcamlab.rig.simulate`,
generator ``tcamlab.rig``) makes one experiment of the kind from its template
(``tcamlab/templates/<kind>.toml``, the kind's default run count) with

* ``parameter_error=1``: every parameter with a stated sd gets a TRUE value
  drawn with the stated value as mean and the stated sd as sd
  (:mod:`tcamlab.rig.lies`; the template's ``[rig.uncertainty]`` plus the
  kind's ``benchmark_uncertainty`` where the template states none);
* ``noisy_zero=True``: each run zeroed on one noisy reading;

and the case's seed ``--seed + KIND_SEED_OFFSET[kind] + i`` (recorded per
case). With ``--priors stated`` (default) the benchmark then writes the sds
the truth was drawn with into the experiment file (``[sample.uncertainty]``,
``[rig.uncertainty]``), as a lab states what it believes, so calibrate's
priors are the distribution of the truth; ``--priors default`` leaves the
file as the rig wrote it (calibrate then uses each kind's documented default
prior sd where the file states none). :func:`tcamlab.calibration.calibrate`
runs on the experiment file and logs only; the truth file
(``truth/<name>.truth.json``) is read afterwards to score.

Measures per kind (scoring functions below, tested in
``tests/test_bench_calibration_coverage.py``):

* coverage: the fraction of (case, parameter) pairs whose 95 % profile
  interval (and, apart, the Laplace interval) contains the true value, per
  parameter and pooled, with a Clopper-Pearson 95 % interval on the fraction
  (the pooled one treats a case's parameters as independent, which they are
  not quite);
* pinned-closer: among parameters the identifiability report calls pinned
  and whose truth was drawn away from the stated value, the fraction whose
  calibrated value is closer to the truth than the stated one;
* z-RMS: the RMS of (calibrated - true) / posterior sd (log space for
  positive parameters); about 1 when the intervals are honest, above 1 when
  they are too narrow;
* failures: the fraction of cases where calibrate raised or returned a
  non-finite value or interval; seconds of calibrate per case.

Targets: coverage >= 90 % over >= 100 cases per kind;
pinned-closer >= 90 %.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import sys
import tempfile
import time
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from pathlib import Path

KINDS = ("static", "dynamic", "sensing", "curvature")
KIND_SEED_OFFSET = {"static": 0, "dynamic": 100_000, "sensing": 200_000, "curvature": 300_000}
"""Case i of a kind has seed ``base + offset + i``: distinct seeds across kinds (the rig's
parameter draws are keyed by seed and field, so equal seeds would repeat E's draw)."""
PARAMETER_ERROR = 1.0
COVERAGE_TARGET = 0.90
PINNED_CLOSER_TARGET = 0.90
MIN_CASES_TARGET = 100
GENERATOR = "tcamlab.rig"


# --- scoring (pure functions; imported by the tests) ------------------------------------------


def contains(interval, x: float) -> bool:
    """Whether ``lo <= x <= hi``; False for a missing or non-finite interval or value."""
    if interval is None:
        return False
    lo, hi = (float(v) for v in interval)
    if not all(math.isfinite(v) for v in (lo, hi, float(x))):
        return False
    return min(lo, hi) <= x <= max(lo, hi)


def binomial_ci(k: int, n: int, level: float = 0.95) -> tuple[float, float]:
    """Clopper-Pearson (exact) interval of a binomial fraction k / n; (nan, nan) for n = 0."""
    if n <= 0:
        return (math.nan, math.nan)
    from scipy.stats import binomtest

    ci = binomtest(int(k), int(n)).proportion_ci(confidence_level=level, method="exact")
    return (float(ci.low), float(ci.high))


def closer_than_stated(value: float, stated: float, true: float) -> bool:
    """Whether the calibrated value is strictly closer to the truth than the stated one."""
    return abs(float(value) - float(true)) < abs(float(stated) - float(true))


def predicted_closer(p: dict) -> float:
    """P(calibrated closer to the truth than stated) for a truth drawn from the prior,
    (2/pi) atan(prior sd / posterior sd) in relative terms
    (:func:`tcamlab.calibration.identify.closer_probability`); nan without the sds."""
    from tcamlab.calibration.identify import closer_probability

    try:
        post = float(p["posterior_sd"]) / abs(float(p["value"]))
        prior = float(p["prior_sd"]) / abs(float(p["stated"]))
    except (KeyError, TypeError, ZeroDivisionError):
        return math.nan
    if not (math.isfinite(post) and math.isfinite(prior) and prior > 0):
        return math.nan
    return closer_probability(post / prior)


def standardized_error(
    value: float, true: float, posterior_sd: float, rel_sd: float, positive: bool
) -> float:
    """(value - true) / posterior sd [-], in log space (relative sd) for a positive parameter."""
    if positive and value > 0 and true > 0 and rel_sd > 0:
        return (math.log(value) - math.log(true)) / rel_sd
    return (value - true) / posterior_sd if posterior_sd > 0 else math.nan


def fraction(k: int, n: int) -> dict:
    """{k, n, fraction, ci95} of a binomial count."""
    lo, hi = binomial_ci(k, n)
    return {"k": int(k), "n": int(n), "fraction": k / n if n else math.nan, "ci95": [lo, hi]}


def _params_of(cases: list[dict]) -> list[str]:
    names: list[str] = []
    for c in cases:
        for p in c.get("parameters", []):
            if p["name"] not in names:
                names.append(p["name"])
    return names


def summarise_kind(cases: list[dict]) -> dict:
    """Coverage, pinned-closer, failures and time of one kind's case records (skipped ones apart)."""
    skipped = [c for c in cases if c.get("skipped")]
    cases = [c for c in cases if not c.get("skipped")]
    ok = [c for c in cases if not c["failed"]]
    rows = [p for c in ok for p in c["parameters"]]
    per = {}
    for name in _params_of(ok):
        ps = [p for p in rows if p["name"] == name]
        zs = [p["z"] for p in ps if math.isfinite(p["z"])]
        pinned = [p for p in ps if p["pinned"] and p["drawn"]]
        drawn = [p for p in ps if p["drawn"]]
        expected = [x for x in map(predicted_closer, drawn) if math.isfinite(x)]
        per[name] = {
            "symbol": ps[0]["symbol"],
            "profile": fraction(sum(p["in_profile"] for p in ps), len(ps)),
            "laplace": fraction(sum(p["in_laplace"] for p in ps), len(ps)),
            "pinned_closer": fraction(sum(p["closer"] for p in pinned), len(pinned)),
            "pinned": sum(p["pinned"] for p in ps),
            "drawn": sum(p["drawn"] for p in ps),
            # every drawn case, pinned or not: does (2/pi) atan(prior/posterior) predict it?
            "closer_drawn": fraction(sum(p["closer"] for p in drawn), len(drawn)),
            "closer_predicted": statistics.fmean(expected) if expected else math.nan,
            "open_bounds": sum(any(p["profile_open"]) for p in ps),
            "z_rms": math.sqrt(statistics.fmean(z * z for z in zs)) if zs else math.nan,
            "z_mean": statistics.fmean(zs) if zs else math.nan,
        }
    pinned = [p for p in rows if p["pinned"] and p["drawn"]]
    secs = [c["seconds"] for c in ok]
    return {
        "cases": len(cases),
        "skipped": len(skipped),
        "skipped_reasons": sorted({c["error"][:120] for c in skipped}),
        "failed": fraction(sum(c["failed"] for c in cases), len(cases)),
        "profile": fraction(sum(p["in_profile"] for p in rows), len(rows)),
        "laplace": fraction(sum(p["in_laplace"] for p in rows), len(rows)),
        "pinned_closer": fraction(sum(p["closer"] for p in pinned), len(pinned)),
        "seconds_median": statistics.median(secs) if secs else math.nan,
        "seconds_mean": statistics.fmean(secs) if secs else math.nan,
        "parameters": per,
        "errors": sorted({c["error"] for c in cases if c["failed"]}),
    }


def verdict(summary: dict) -> str:
    """PASS / FAIL against the issue's targets (n >= 100, coverage >= 90 %, pinned-closer >= 90 %)."""
    cov = summary["profile"]["fraction"]
    closer = summary["pinned_closer"]
    enough = summary["cases"] >= MIN_CASES_TARGET
    good = cov >= COVERAGE_TARGET and (closer["n"] == 0 or closer["fraction"] >= PINNED_CLOSER_TARGET)
    if not good:
        return "FAIL"
    return "PASS" if enough else f"pass (n < {MIN_CASES_TARGET})"


# --- one case ---------------------------------------------------------------------------------


def _state_priors(exp_path: Path, sds: dict) -> None:
    """Write the sds the truth was drawn with into the experiment file, in lab units."""
    import tomllib

    from tcamlab.config import write_experiment
    from tcamlab.params import RIG_KEYS, SAMPLE_KEYS

    doc = tomllib.loads(exp_path.read_text())
    for table, keys in (("sample", SAMPLE_KEYS), ("rig", RIG_KEYS)):
        unc = doc.setdefault(table, {}).get("uncertainty", {})
        for key, (si, factor) in keys.items():
            if si in sds and not isinstance(sds[si], (list, tuple)):
                unc[key] = float(sds[si]) / factor
        if unc:
            doc[table]["uncertainty"] = unc
    write_experiment(exp_path, doc)


def _true_value(truth: dict, where: str, fld: str) -> tuple[float, bool, float]:
    """(true value [SI], whether it was drawn off the stated one, its relative spread over runs)."""
    runs = [r[where][fld] for r in truth["runs"] if r[where].get(fld) is not None]
    drawn = truth.get("true_parameters", {}).get(fld)
    true = float(drawn["true"]) if drawn else float(runs[0])
    spread = (max(runs) - min(runs)) / abs(true) if runs and true else 0.0
    return true, drawn is not None, spread


def _score_parameter(p, truth: dict) -> dict:
    true, drawn, spread = _true_value(truth, p.where, p.field)
    positive = p.stated > 0 and p.value > 0
    return {
        "name": p.name,
        "field": p.field,
        "symbol": p.symbol,
        "stated": p.stated,
        "stated_in_file": p.stated_in_file,
        "prior_sd": p.prior_sd,
        "true": true,
        "drawn": drawn and p.stated_in_file,
        "offset_sd": (true - p.stated) / p.prior_sd if p.prior_sd else math.nan,
        "run_spread_rel": spread,
        "value": p.value,
        "posterior_sd": p.posterior_sd,
        "laplace_95": list(p.laplace_95),
        "profile_95": list(p.profile_95),
        "profile_open": list(p.profile_open),
        "pinned": bool(p.pinned),
        "in_profile": contains(p.profile_95, true),
        "in_laplace": contains(p.laplace_95, true),
        "closer": closer_than_stated(p.value, p.stated, true),
        "z": standardized_error(p.value, true, p.posterior_sd, p.posterior_sd_rel, positive),
    }


def _finite(result) -> bool:
    vals = [v for p in result.parameters for v in (p.value, *p.profile_95, *p.laplace_95)]
    return all(math.isfinite(v) for v in vals)


def _simulate(kind: str, seed: int, tmp: str, priors: str):
    """The lying experiment of one case (and its stated priors written in), or raise TcamlabError."""
    from tcamlab.kinds import get_kind
    from tcamlab.rig import simulate
    from tcamlab.templates import template_path

    sim = simulate(
        kind,
        template_path(kind),
        seed=int(seed),
        out_dir=tmp,
        parameter_error=PARAMETER_ERROR,
        noisy_zero=True,
        uncertainty=dict(get_kind(kind).benchmark_uncertainty),
    )
    if priors == "stated":
        _state_priors(Path(sim.experiment_path), sim.truth.get("stated_sd", {}))
    return sim


def run_case(kind: str, seed: int, priors: str = "stated") -> dict:
    """Simulate one lying experiment, calibrate it, score it against the truth file.

    A truth the rig cannot run (the drawn parameters leave the model's domain, e.g. a small
    C_th heating the dynamic actuator past G_t' = 0) is ``skipped``, not a failed fit.
    """
    from tcamlab.calibration import calibrate
    from tcamlab.errors import TcamlabError

    rec = {"kind": kind, "seed": int(seed), "skipped": False, "failed": False, "error": "", "parameters": []}
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        try:
            sim = _simulate(kind, seed, tmp, priors)
        except TcamlabError as exc:
            rec.update(skipped=True, error=f"rig: {type(exc).__name__}: {exc}"[:300])
            return rec
        rec["simulate_seconds"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        try:
            result = calibrate([sim.experiment_path])
        except Exception as exc:  # a failed fit is a measured outcome, not a crash of the benchmark
            rec.update(failed=True, error=f"{type(exc).__name__}: {exc}"[:300])
            rec["seconds"] = time.perf_counter() - t0
            return rec
        rec["seconds"] = time.perf_counter() - t0
    if not _finite(result):
        rec.update(failed=True, error="non-finite value or interval")
    rec["parameters"] = [_score_parameter(p, sim.truth) for p in result.parameters]
    # every drawn parameter, calibrated or not (an uncalibrated one is a model error the fit absorbs)
    rec["drawn_offsets_sd"] = {f: v["offset_sd"] for f, v in sim.truth.get("true_parameters", {}).items()}
    rec["rmse_over_sigma"] = {f.quantity: f.rmse_over_sigma_calibrated for f in result.fit}
    rec["identifiability"] = result.identifiability
    return rec


# --- the run ----------------------------------------------------------------------------------


class Schedule:
    """Cases to run: ``n`` scored (not skipped) cases per kind, round-robin over the kinds.

    Case i of a kind has seed ``base + KIND_SEED_OFFSET[kind] + i``; a skipped case (truth
    outside the model's domain) is replaced by the kind's next seed. ``done`` are records of an
    earlier run with the same settings (``--resume``), counted and not run again.
    """

    def __init__(self, kinds, n: int, base: int, done: list[dict]):
        self.kinds, self.n, self.base = list(kinds), int(n), int(base)
        self.seen = {(c["kind"], c["seed"]) for c in done}
        self.scored = {k: sum(c["kind"] == k and not c.get("skipped") for c in done) for k in self.kinds}
        self.running = {k: 0 for k in self.kinds}
        self.next_i = {k: 0 for k in self.kinds}

    def next(self) -> tuple[str, int] | None:
        need = [k for k in self.kinds if self.scored[k] + self.running[k] < self.n]
        if not need:
            return None
        kind = min(need, key=lambda k: self.scored[k] + self.running[k])
        while (kind, seed := self.base + KIND_SEED_OFFSET[kind] + self.next_i[kind]) in self.seen:
            self.next_i[kind] += 1
        self.next_i[kind] += 1
        self.running[kind] += 1
        return kind, seed

    def finished(self, rec: dict) -> None:
        self.running[rec["kind"]] -= 1
        self.scored[rec["kind"]] += not rec["skipped"]


def _report(rec: dict, sched: Schedule, log) -> None:
    if rec["skipped"] or rec["failed"]:
        mark = ("SKIPPED " if rec["skipped"] else "FAILED ") + rec["error"]
    else:
        mark = f"{rec['seconds']:.1f} s"
    done = sum(sched.scored.values())
    total = sched.n * len(sched.kinds)
    print(f"[{done}/{total}] {rec['kind']} seed {rec['seed']}: {mark}", file=sys.stderr, flush=True)
    log.write(json.dumps(rec) + "\n")
    log.flush()


def run_all(sched: Schedule, jobs: int, priors: str, log_path: Path | None) -> list[dict]:
    """Run the schedule in ``jobs`` processes; each finished case is appended to ``log_path`` (JSON lines)."""
    out: list[dict] = []
    with open(log_path or os.devnull, "a") as log:
        if jobs <= 1:
            while (task := sched.next()) is not None:
                out.append(run_case(*task, priors))
                sched.finished(out[-1])
                _report(out[-1], sched, log)
            return out
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            pending = set()
            while True:
                while len(pending) < jobs and (task := sched.next()) is not None:
                    pending.add(pool.submit(run_case, *task, priors))
                if not pending:
                    return out
                finished, pending = wait(pending, return_when=FIRST_COMPLETED)
                for f in finished:
                    out.append(f.result())
                    sched.finished(out[-1])
                    _report(out[-1], sched, log)


def _pct(f: dict) -> str:
    if not f["n"]:
        return "-"
    lo, hi = f["ci95"]
    return f"{100 * f['fraction']:.1f}% ({f['k']}/{f['n']}; {100 * lo:.0f}-{100 * hi:.0f})"


def markdown(summaries: dict, meta: dict) -> str:
    """The per-kind table and the per-parameter table."""
    lines = [
        "| kind | cases | profile 95% coverage (k/n; 95% CI) | Laplace coverage | pinned closer than stated"
        " | failed | s/case (median) | target |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for kind, s in summaries.items():
        n = f"{s['cases']} (+{s['skipped']} skipped)" if s["skipped"] else str(s["cases"])
        lines.append(
            f"| {kind} | {n} | {_pct(s['profile'])} | {_pct(s['laplace'])} | {_pct(s['pinned_closer'])}"
            f" | {s['failed']['k']}/{s['cases']} | {s['seconds_median']:.1f} | {verdict(s)} |"
        )
    lines += [
        "",
        "| kind | parameter | profile coverage | Laplace coverage | pinned (drawn) | pinned closer |"
        " z-RMS | mean z | open bounds | closer, all drawn (predicted) |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for kind, s in summaries.items():
        for name, p in s["parameters"].items():
            lines.append(
                f"| {kind} | {name} ({p['symbol']}) | {_pct(p['profile'])} | {_pct(p['laplace'])} |"
                f" {p['pinned']} ({p['drawn']}) | {_pct(p['pinned_closer'])} | {p['z_rms']:.2f} |"
                f" {p['z_mean']:+.2f} | {p['open_bounds']} | {_pct(p['closer_drawn'])}"
                + (f" ({p['closer_predicted']:.3f}) |" if math.isfinite(p["closer_predicted"]) else " |")
            )
    lines += [
        "",
        f"Synthetic data: generator {meta['generator']}, parameter_error {meta['parameter_error']:g},"
        f" noisy zeros, priors {meta['priors']}, case seeds base {meta['seed']} + kind offset"
        f" {meta['kind_seed_offset']} + i; "
        + (
            f"summarised from {', '.join(meta['from_cases'])}."
            if meta.get("from_cases")
            else f"{meta['jobs']} worker(s)."
        ),
    ]
    return "\n".join(lines) + "\n"


def _parse(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kinds", default=",".join(KINDS), help="comma-separated kinds (default all four)")
    ap.add_argument("--cases", type=int, default=100, help="cases per kind (default 100)")
    ap.add_argument("--seed", type=int, default=0, help="base seed (default 0)")
    ap.add_argument("--jobs", type=int, default=1, help="worker processes (default 1)")
    ap.add_argument("--priors", choices=("stated", "default"), default="stated", help="see the docstring")
    ap.add_argument("--out", help="folder for coverage.json, coverage.md and cases.jsonl")
    ap.add_argument("--force", action="store_true", help="overwrite an existing --out folder's files")
    ap.add_argument("--resume", action="store_true", help="keep --out's cases.jsonl and run only the rest")
    ap.add_argument("--quick", action="store_true", help="CI smoke run: 2 cases per kind")
    ap.add_argument(
        "--from-cases",
        nargs="+",
        metavar="JSONL",
        help="summarise finished cases (cases.jsonl of earlier runs) instead of running any",
    )
    args = ap.parse_args(argv)
    args.kinds = [k.strip() for k in args.kinds.split(",") if k.strip()]
    bad = [k for k in args.kinds if k not in KINDS]
    if bad or args.cases < 1 or args.jobs < 1 or args.seed < 0:
        ap.error(f"--kinds from {', '.join(KINDS)}; --cases and --jobs >= 1; --seed >= 0 (got {bad or ''})")
    if args.quick:
        args.cases = 2
    return args


def _prepare_out(args) -> tuple[Path | None, list[dict]]:
    """The --out folder, created, and the cases an earlier run left there (--resume)."""
    if not args.out:
        return None, []
    out = Path(args.out)
    files = [out / f for f in ("coverage.json", "coverage.md", "cases.jsonl")]
    done: list[dict] = []
    if args.resume and files[2].exists():
        done = [json.loads(line) for line in files[2].read_text().splitlines() if line.strip()]
        done = [c for c in done if c["kind"] in args.kinds]
    elif any(f.exists() for f in files):
        if not args.force:
            print(
                f"error: {out} already holds results (hint: --force to overwrite, --resume to finish)",
                file=sys.stderr,
            )
            raise SystemExit(2)
        for f in files:
            f.unlink(missing_ok=True)
    out.mkdir(parents=True, exist_ok=True)
    return out, done


def main(argv=None) -> int:
    args = _parse(argv)
    t0 = time.perf_counter()
    if args.from_cases:
        out = None
        cases = [
            json.loads(ln) for f in args.from_cases for ln in Path(f).read_text().splitlines() if ln.strip()
        ]
        args.kinds = [k for k in KINDS if any(c["kind"] == k for c in cases)]
    else:
        out, done = _prepare_out(args)
        if args.jobs > 1:
            os.environ.setdefault("NUMBA_NUM_THREADS", "1")  # the processes share the cores
        sched = Schedule(args.kinds, args.cases, args.seed, done)
        cases = done + run_all(sched, args.jobs, args.priors, out and out / "cases.jsonl")
    cases.sort(key=lambda c: (KINDS.index(c["kind"]), c["seed"]))
    summaries = {k: summarise_kind([c for c in cases if c["kind"] == k]) for k in args.kinds}
    meta = {
        "generator": GENERATOR,
        "parameter_error": PARAMETER_ERROR,
        "noisy_zero": True,
        "priors": args.priors,
        "seed": args.seed,
        "kind_seed_offset": KIND_SEED_OFFSET,
        "cases_per_kind": args.cases,
        "jobs": args.jobs,
        "from_cases": args.from_cases or [],
        "wall_seconds": time.perf_counter() - t0,
    }
    table = markdown(summaries, meta)
    print(table)
    if out:
        (out / "coverage.md").write_text(table)
        doc = {"meta": meta, "summaries": summaries, "cases": cases}
        (out / "coverage.json").write_text(json.dumps(doc, indent=1, default=str))
    return 0


if __name__ == "__main__":
    sys.exit(main())  # spawned workers re-import this file; keep the guard
