#!/usr/bin/env python
"""End-to-end speed of the tcamlab pipeline: ingest, ``tcamlab report``, ``--help``.

Run from the repository root::

    python bench/bench_pipeline.py                  # 10,000,000-row ingest (~1-2 min)
    python bench/bench_pipeline.py --rows 1000000   # smaller ingest file
    python bench/bench_pipeline.py --json out.json  # also write every number as JSON
    python bench/bench_pipeline.py --only ingest    # a subset: ingest, report, help
    python bench/bench_pipeline.py --profile        # also cProfile read_run (where time goes)

Figures (see bench/README.md):

a. Ingest - a synthetic 1 kHz dynamic log (``time_s,voltage_V,displacement_mm,
   temperature_C``) is written in chunks to a temporary directory; then
   ``tcamlab.io.read_run(path, "dynamic")`` runs in a fresh subprocess
   (wall time of the call, peak RSS from ``getrusage(RUSAGE_SELF).ru_maxrss``
   in that subprocess; best of 3 fresh subprocesses), and so does a plain
   ``pandas.read_csv(path)`` as the reference. The file is deleted afterwards.
b. ``python -m tcamlab report --out <tmp>/reports`` on a temporary copy of the
   repository's ``experiments/`` and ``raw/`` folders, best of 3 subprocess
   runs, with the per-experiment split taken from its progress lines.
c. ``python -m tcamlab --help``: median of 5 subprocess runs (bench_cli_help.py).

Nothing asserts on time; each row prints PASS or FAIL against its goal.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
MB = 1e6  # report megabytes as 10^6 bytes; ru_maxrss is in KiB on Linux

INGEST_TIME_GOAL_S = 15.0
INGEST_RSS_GOAL_MB = 3000.0
REPORT_GOAL_S = 20.0
HELP_GOAL_S = 0.5


# --------------------------------------------------------------------------- helpers
def fmt_time(s):
    if s is None:
        return "-"
    if s >= 1:
        return f"{s:.2f} s"
    if s >= 1e-3:
        return f"{s * 1e3:.0f} ms"
    return f"{s * 1e6:.0f} us"


def env_info():
    # Versions from the metadata, not by importing: this process stays small
    # (see run_child).
    from importlib.metadata import version

    try:
        affinity = len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        affinity = os.cpu_count()
    return {
        "date": _dt.date.today().isoformat(),
        "python": platform.python_version(),
        "numpy": version("numpy"),
        "pandas": version("pandas"),
        "cpus": os.cpu_count(),
        "nproc": affinity,
        "machine": platform.machine(),
        "system": f"{platform.system()} {platform.release()}",
    }


# --------------------------------------------------------------------------- a. ingest
def write_dynamic_log(path: Path, rows: int, chunk: int = 1_000_000, seed: int = 0) -> dict:
    """Write a realistic 1 kHz dynamic log of ``rows`` rows, ``chunk`` rows at a time.

    A 10 V, 2 s heating pulse every 20 s; the fiber temperature follows a
    first-order lag (tau 1.8 s, 60 K steady rise), the coil contracts 0.08 mm/K.
    The measurement chain copies the rig's: laser on a 10-bit ADC over 10 mm
    (0.00978 mm steps, tared on the first row, 3 decimals), thermocouple amp
    with 0.25 degC steps, voltage with 3 mV noise; every column printed with
    3 decimals (``%.3f``), like the rig's logger.
    """
    import numpy as np
    import pandas as pd

    rng = np.random.default_rng(seed)
    rate, period, on, volts = 1000.0, 20.0, 2.0, 10.0
    tau, dT_ss, k_mm_per_K, ambient = 1.8, 60.0, 0.08, 24.0
    q_laser = 10.0 / (2**10 - 1)  # mm per ADC code
    rest_code = None
    t0 = time.perf_counter()
    with open(path, "w", newline="\n") as fh:
        fh.write("time_s,voltage_V,displacement_mm,temperature_C\n")
        for start in range(0, rows, chunk):
            k = np.arange(start, min(start + chunk, rows), dtype=np.int64)
            t = k / rate
            phase = np.mod(t, period)
            heating = phase < on
            rise_end = dT_ss * (1.0 - np.exp(-on / tau))
            dT = np.where(
                heating, dT_ss * (1.0 - np.exp(-phase / tau)), rise_end * np.exp(-(phase - on) / tau)
            )
            v = np.where(heating, volts, 0.0) + rng.normal(0.0, 0.003, k.size)
            x_true = 5.0 - k_mm_per_K * dT + rng.normal(0.0, 0.005, k.size)  # mm on the laser
            codes = np.clip(np.round(x_true / q_laser), 0, 2**10 - 1)
            if rest_code is None:
                rest_code = codes[0]
            disp = (codes - rest_code) * q_laser
            temp = np.round((ambient + dT + rng.normal(0.0, 0.15, k.size)) / 0.25) * 0.25
            frame = pd.DataFrame(
                {"time_s": t, "voltage_V": v, "displacement_mm": disp, "temperature_C": temp}
            )
            frame.to_csv(fh, header=False, index=False, float_format="%.3f", lineterminator="\n")
    return {"rows": rows, "bytes": path.stat().st_size, "write_s": time.perf_counter() - t0}


_CHILD_READ_RUN = r"""
import json, resource, sys, time
t0 = time.perf_counter()
import tcamlab.io as tio
t_import = time.perf_counter() - t0
rss_import = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
t0 = time.perf_counter()
run = tio.read_run(sys.argv[1], "dynamic")
t_call = time.perf_counter() - t0
rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
hwm = next((int(l.split()[1]) for l in open("/proc/self/status") if l.startswith("VmHWM")), -1)
print(json.dumps({"import_s": t_import, "call_s": t_call, "rss_import_kib": rss_import,
                  "rss_kib": rss, "hwm_kib": hwm, "rows": len(run.data),
                  "columns": list(run.data.columns),
                  "frame_bytes": int(run.data.memory_usage(deep=True).sum())}))
"""

_CHILD_PANDAS = r"""
import json, resource, sys, time
t0 = time.perf_counter()
import pandas as pd
t_import = time.perf_counter() - t0
rss_import = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
t0 = time.perf_counter()
df = pd.read_csv(sys.argv[1])
t_call = time.perf_counter() - t0
rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
hwm = next((int(l.split()[1]) for l in open("/proc/self/status") if l.startswith("VmHWM")), -1)
print(json.dumps({"import_s": t_import, "call_s": t_call, "rss_import_kib": rss_import,
                  "rss_kib": rss, "hwm_kib": hwm, "rows": len(df), "columns": list(df.columns),
                  "frame_bytes": int(df.memory_usage(deep=True).sum())}))
"""

_CHILD_PROFILE = r"""
import cProfile, io, pstats, sys
import tcamlab.io as tio
pr = cProfile.Profile()
pr.enable()
tio.read_run(sys.argv[1], "dynamic")
pr.disable()
buf = io.StringIO()
st = pstats.Stats(pr, stream=buf)
st.sort_stats("tottime").print_stats(12)
print(buf.getvalue())
"""


def run_child(code: str, path: Path) -> dict:
    """Run ``code`` in a fresh interpreter; its JSON line plus wall time and MB figures.

    Linux carries the parent's resident size into a child's ``ru_maxrss``
    (fork copies the high-water mark, execve keeps it), so this process keeps
    itself small: it never imports numpy or pandas and writes the log from a
    subprocess too. ``VmHWM`` of ``/proc/self/status`` (the child's own
    address space only) is reported next to it as a check.
    """
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True, text=True, cwd=REPO)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        tail = (proc.stderr.strip().splitlines() or ["(no output)"])[-1]
        raise RuntimeError(f"child exited {proc.returncode}: {tail}")
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    out["wall_s"] = wall
    out["rss_mb"] = out["rss_kib"] * 1024 / MB
    out["rss_import_mb"] = out["rss_import_kib"] * 1024 / MB
    out["hwm_mb"] = out["hwm_kib"] * 1024 / MB if out.get("hwm_kib", -1) >= 0 else None
    return out


def generate_in_subprocess(path: Path, rows: int) -> dict:
    proc = subprocess.run(
        [sys.executable, __file__, "--generate", str(path), "--rows", str(rows)],
        capture_output=True,
        text=True,
    )
    if proc.returncode != 0:
        tail = (proc.stderr.strip().splitlines() or ["(no output)"])[-1]
        raise RuntimeError(f"log generation exited {proc.returncode}: {tail}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def bench_ingest(args) -> dict:
    tmp = Path(tempfile.mkdtemp(prefix="tcamlab-bench-ingest-"))
    path = tmp / "dynamic_1khz.csv"
    try:
        gen = generate_in_subprocess(path, args.rows)
        print(
            f"[ingest: wrote {gen['rows']:,} rows, {gen['bytes'] / MB:.0f} MB in {gen['write_s']:.1f} s]",
            file=sys.stderr,
            flush=True,
        )
        # Reference first, then tcamlab; both find the file in the page cache
        # (it was just written), so neither pays for the disk.
        # Alternate the two readers so a noisy neighbour hits both alike.
        ref_all, fast_all = [], []
        for _ in range(args.repeats):
            ref_all.append(run_child(_CHILD_PANDAS, path))
            fast_all.append(run_child(_CHILD_READ_RUN, path))
        ref = min(ref_all, key=lambda r: r["call_s"])
        fast = min(fast_all, key=lambda r: r["call_s"])
        profile = None
        if args.profile:
            proc = subprocess.run(
                [sys.executable, "-c", _CHILD_PROFILE, str(path)], capture_output=True, text=True, cwd=REPO
            )
            profile = proc.stdout if proc.returncode == 0 else proc.stderr
        t_ratio = fast["call_s"] / ref["call_s"]
        m_ratio = fast["rss_mb"] / ref["rss_mb"]
        ok = fast["call_s"] < INGEST_TIME_GOAL_S and fast["rss_mb"] < INGEST_RSS_GOAL_MB
        notes = [
            f"ingest: file {gen['rows']:,} rows x 4 columns, {gen['bytes'] / MB:.0f} MB "
            f"(generated in {gen['write_s']:.1f} s, page-cache warm); fastest of {args.repeats} "
            f"fresh subprocess(es) each; read_run calls "
            f"{', '.join(fmt_time(r['call_s']) for r in fast_all)}, read_csv calls "
            f"{', '.join(fmt_time(r['call_s']) for r in ref_all)}",
            f"ingest: read_run call {fast['call_s']:.2f} s (+ import {fast['import_s']:.2f} s, "
            f"subprocess wall {fast['wall_s']:.2f} s); peak RSS {fast['rss_mb']:.0f} MB "
            f"({fast['rss_import_mb']:.0f} MB after imports; VmHWM {fast['hwm_mb']:.0f} MB); "
            "result frame "
            f"{fast['frame_bytes'] / MB:.0f} MB, columns {', '.join(fast['columns'])}",
            f"ingest: pandas.read_csv call {ref['call_s']:.2f} s (+ import {ref['import_s']:.2f} s)"
            f"; peak RSS {ref['rss_mb']:.0f} MB ({ref['rss_import_mb']:.0f} MB after imports; "
            f"VmHWM {ref['hwm_mb']:.0f} MB); "
            f"frame {ref['frame_bytes'] / MB:.0f} MB",
        ]
        return {
            "figure": 'a. ingest: tcamlab.io.read_run(path, "dynamic")',
            "size": f"{gen['rows']:,} rows, {gen['bytes'] / MB:.0f} MB CSV",
            "time": f"{fast['call_s']:.2f} s, peak RSS {fast['rss_mb']:,.0f} MB",
            "reference": f"pandas.read_csv: {ref['call_s']:.2f} s, {ref['rss_mb']:,.0f} MB",
            "ratio": f"{t_ratio:.2f}x time, {m_ratio:.2f}x RSS",
            "goal": f"< {INGEST_TIME_GOAL_S:g} s, < {INGEST_RSS_GOAL_MB / 1000:g} GB RSS",
            "result": "PASS" if ok else "FAIL",
            "pass": ok,
            "time_s": fast["call_s"],
            "rss_mb": fast["rss_mb"],
            "ref_time_s": ref["call_s"],
            "ref_rss_mb": ref["rss_mb"],
            "time_ratio": t_ratio,
            "rss_ratio": m_ratio,
            "read_run": fast,
            "pandas": ref,
            "read_run_all": fast_all,
            "pandas_all": ref_all,
            "file": gen,
            "profile": profile,
            "notes": notes,
        }
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


# --------------------------------------------------------------------------- b. report
def _timed_report(cwd: Path, out: Path) -> dict:
    """One ``python -m tcamlab report`` subprocess; progress lines time-stamped."""
    shutil.rmtree(out, ignore_errors=True)
    stdout_lines: list[str] = []
    env = dict(os.environ)
    env.pop("CI", None)  # stderr is a pipe: the CLI prints one progress line per experiment
    t0 = time.perf_counter()
    proc = subprocess.Popen(
        [sys.executable, "-m", "tcamlab", "report", "--out", str(out)],
        cwd=cwd,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
    reader = threading.Thread(target=lambda: stdout_lines.extend(proc.stdout), daemon=True)
    reader.start()
    marks: list[tuple[float, str]] = []
    other_err: list[str] = []
    for line in proc.stderr:
        now = time.perf_counter() - t0
        line = line.rstrip("\n")
        if line.startswith("[") and "validating" in line:
            marks.append((now, line.split("validating", 1)[1].strip()))
        else:
            other_err.append(line)
    proc.wait()
    reader.join()
    wall = time.perf_counter() - t0
    # Segments: start-up (imports) until the first progress line; experiment i
    # from its line to the next; the last one also holds index.html + reports.pdf.
    segments = []
    if marks:
        segments.append(("start-up (imports, before the first experiment)", marks[0][0]))
        for i, (t, name) in enumerate(marks):
            end = marks[i + 1][0] if i + 1 < len(marks) else wall
            label = name if i + 1 < len(marks) else f"{name} + index.html + reports.pdf"
            segments.append((label, end - t))
    return {
        "wall_s": wall,
        "returncode": proc.returncode,
        "segments": segments,
        "stdout": [s.rstrip("\n") for s in stdout_lines],
        "stderr_other": other_err,
    }


def bench_report(args) -> dict:
    figure = "b. python -m tcamlab report --out <tmp>/reports"
    goal = f"< {REPORT_GOAL_S:g} s (best of {args.report_runs})"
    exps = sorted((REPO / "experiments").glob("*.toml"))
    if not exps:
        return {
            "figure": figure,
            "size": "sample data not available",
            "time": "-",
            "reference": "-",
            "ratio": "-",
            "goal": goal,
            "result": "n/a",
            "pass": None,
            "notes": ["report: sample data not available (experiments/*.toml is empty)"],
        }
    tmp = Path(tempfile.mkdtemp(prefix="tcamlab-bench-report-"))
    try:
        for name in ("experiments", "raw"):
            if (REPO / name).is_dir():
                shutil.copytree(REPO / name, tmp / name)
        n_raw = sum(1 for p in (tmp / "raw").rglob("*") if p.is_file()) if (tmp / "raw").is_dir() else 0
        raw_mb = (
            sum(p.stat().st_size for p in (tmp / "raw").rglob("*") if p.is_file()) / MB
            if (tmp / "raw").is_dir()
            else 0.0
        )
        runs = []
        for i in range(args.report_runs):
            r = _timed_report(tmp, tmp / "reports")
            runs.append(r)
            print(
                f"[report run {i + 1}: {r['wall_s']:.2f} s, exit {r['returncode']}]",
                file=sys.stderr,
                flush=True,
            )
        best = min(runs, key=lambda r: r["wall_s"])
        completed = all(r["returncode"] in (0, 1) for r in runs)
        ok = completed and best["wall_s"] < REPORT_GOAL_S
        status = {
            0: "all experiments pass",
            1: "ran; some experiment fails its thresholds",
            2: "ran; some experiment errored",
        }.get(best["returncode"], f"exit {best['returncode']}")
        notes = [
            f"report: {len(exps)} experiment files, {n_raw} raw files ({raw_mb:.1f} MB); "
            f"runs {', '.join(fmt_time(r['wall_s']) for r in runs)} (exit "
            f"{', '.join(str(r['returncode']) for r in runs)}: {status})",
            "report: split of the best run: "
            + "; ".join(
                f"{label} {fmt_time(s)} ({100 * s / best['wall_s']:.0f}%)" for label, s in best["segments"]
            ),
            "report: CLI output of the best run: " + " | ".join(best["stdout"]),
        ]
        if best["stderr_other"]:
            notes.append("report: other stderr: " + " | ".join(best["stderr_other"][-5:]))
        return {
            "figure": figure,
            "size": f"{len(exps)} experiments, {n_raw} raw files",
            "time": fmt_time(best["wall_s"]),
            "reference": "- (no meaningful baseline)",
            "ratio": "-",
            "goal": goal,
            "result": ("PASS" if ok else "FAIL") + ("" if completed else " (errors)"),
            "pass": ok,
            "time_s": best["wall_s"],
            "runs_s": [r["wall_s"] for r in runs],
            "returncodes": [r["returncode"] for r in runs],
            "segments": best["segments"],
            "stdout": best["stdout"],
            "notes": notes,
        }
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


# --------------------------------------------------------------------------- c. --help
def bench_help(args) -> dict:
    sys.path.insert(0, str(HERE))
    from bench_cli_help import run_times

    figure = "c. python -m tcamlab --help"
    goal = f"< {HELP_GOAL_S:g} s (median of {args.help_runs})"
    cli = [sys.executable, "-m", "tcamlab", "--help"]
    base = [sys.executable, "-c", "pass"]
    warm = subprocess.run(cli, capture_output=True, text=True, cwd=REPO)
    if warm.returncode != 0:
        return {
            "figure": figure,
            "size": "-",
            "time": "CLI not available",
            "reference": "-",
            "ratio": "-",
            "goal": goal,
            "result": "n/a",
            "pass": None,
            "notes": [],
        }
    subprocess.run(base, capture_output=True)
    cli_t, _ = run_times(cli, args.help_runs)
    base_t, _ = run_times(base, args.help_runs)
    cli_med, base_med = statistics.median(cli_t), statistics.median(base_t)
    ok = cli_med < HELP_GOAL_S
    return {
        "figure": figure,
        "size": f"{args.help_runs} runs",
        "time": f"{fmt_time(cli_med)} median",
        "reference": f"python -c pass: {fmt_time(base_med)}",
        "ratio": f"{cli_med / base_med:.1f}x",
        "goal": goal,
        "result": "PASS" if ok else "FAIL",
        "pass": ok,
        "time_s": cli_med,
        "ref_time_s": base_med,
        "runs_s": cli_t,
        "baseline_runs_s": base_t,
        "notes": [
            f"--help: min {fmt_time(min(cli_t))}, max {fmt_time(max(cli_t))}; CLI "
            f"overhead over the bare interpreter {fmt_time(cli_med - base_med)}"
        ],
    }


# --------------------------------------------------------------------------- driver
def table(rows) -> str:
    head = ("Figure", "Size", "Time", "Reference", "Ratio", "Goal", "Result")
    keys = ("figure", "size", "time", "reference", "ratio", "goal", "result")
    lines = ["| " + " | ".join(head) + " |", "|" + "|".join("---" for _ in head) + "|"]
    for r in rows:
        lines.append("| " + " | ".join(str(r[k]) for k in keys) + " |")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument(
        "--rows",
        type=int,
        default=10_000_000,
        help="rows of the ingest file (default 10,000,000 = 2.8 h at 1 kHz)",
    )
    ap.add_argument("--json", metavar="PATH", help="also write the results as JSON")
    ap.add_argument(
        "--only", default="ingest,report,help", help="comma-separated subset of: ingest, report, help"
    )
    ap.add_argument(
        "--repeats",
        type=int,
        default=3,
        help="fresh subprocesses per ingest reader; the fastest is kept (default 3)",
    )
    ap.add_argument("--report-runs", type=int, default=3)
    ap.add_argument("--help-runs", type=int, default=5)
    ap.add_argument(
        "--profile",
        action="store_true",
        help="also cProfile read_run in a third subprocess and print the top",
    )
    ap.add_argument(
        "--quick",
        action="store_true",
        help="CI smoke run: 20,000-row ingest file, one run of each figure; exit 1 when a "
        "figure could not run (times are printed, never asserted)",
    )
    ap.add_argument("--generate", metavar="PATH", help=argparse.SUPPRESS)  # internal
    args = ap.parse_args(argv)
    if args.quick and not args.generate:
        args.rows = min(args.rows, 20_000)
        args.repeats = args.report_runs = args.help_runs = 1
    if args.generate:  # child mode: write the log, print its JSON summary
        print(json.dumps(write_dynamic_log(Path(args.generate), args.rows)))
        return 0

    only = {s.strip() for s in args.only.split(",")}
    info = env_info()
    rows = []
    t_start = time.perf_counter()
    for key, fn in (("ingest", bench_ingest), ("report", bench_report), ("help", bench_help)):
        if key in only:
            t0 = time.perf_counter()
            rows.append(fn(args))
            print(f"[{key} done in {time.perf_counter() - t0:.1f} s]", file=sys.stderr, flush=True)
    cmd = "python " + " ".join([os.path.relpath(sys.argv[0])] + (argv or sys.argv[1:]))
    print("## tcamlab pipeline benchmarks\n")
    print(
        f"`{cmd}` - {info['date']}, Python {info['python']}, pandas {info['pandas']}, "
        f"numpy {info['numpy']}, nproc {info['nproc']} ({info['cpus']} CPUs), "
        f"{info['system']} {info['machine']}.\n"
    )
    print(table(rows))
    print()
    for r in rows:
        for note in r.get("notes", []):
            print(f"- {note}")
    for r in rows:
        if r.get("profile"):
            print("\nread_run profile (cProfile, top 12 by own time):\n")
            print("```\n" + r["profile"].strip() + "\n```")
    print(f"\nTotal bench time {time.perf_counter() - t_start:.1f} s.")
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        with open(args.json, "w") as fh:
            json.dump(
                {"command": cmd, **info, "rows_arg": args.rows, "results": rows}, fh, indent=2, default=float
            )
        print(f"JSON written to {args.json}")
    if args.quick:
        broken = [r["figure"] for r in rows if r["result"] == "n/a" or "(errors)" in r["result"]]
        if broken:
            print(f"quick run: could not run {'; '.join(broken)}", file=sys.stderr)
            return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
