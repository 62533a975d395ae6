#!/usr/bin/env python
"""``validate``, ``report``, ``calibrate`` and ``diagnose`` on a long 1 kHz dynamic log: time,
peak RSS, report size.

Run from the repository root::

    python bench/bench_large_log.py            # 10,000,000 rows (about 2.8 h of logging)
    python bench/bench_large_log.py --quick    # 1,000,000 rows; fits on 142,100 (CI)
    python bench/bench_large_log.py --rows N --work DIR --json out.json
    python bench/bench_large_log.py --fit-rows 142100,1000000 --ref-fit-rows 100000
    python bench/bench_large_log.py --check    # CI: 10,000,000 rows, exit 1 if a report is >= 5 MB

The log is SYNTHETIC, made by :func:`make_log` (seed 12, vectorised): a 10 V, 1 s
pulse every 20 s, the thesis dynamic model (``tcamlab.kinds.dynamic.predict`` on the
bundled experiment's sample and rig) evaluated on one 20 s period at 1 kHz and tiled
(the actuator cools to within 0.2% of its rest length before the next pulse), plus
laser noise (sd 5 um) rounded to the logged 1 um. The CSV is cached in ``--work``
(default the system temporary folder) under a name carrying the rows and the seed.

Each measurement runs in a fresh subprocess (wall time and ``ru_maxrss`` of that
process): ``python -m tcamlab validate dynamic`` and ``python -m tcamlab report`` on the
long log, and, in the same run, the straightforward references:

* read: a plain ``pandas.read_csv(path)`` against ``tcamlab.io.read_run``;
* figure: the dynamic figure drawn at full resolution (every row a marker, plain
  matplotlib SVG) against the report's figure (min/max envelope per pixel column).

``calibrate`` and ``diagnose`` run on logs of ``--fit-rows`` rows (default 142,100 -- the
length of a real 1 kHz log joined with a thermal camera --, 1,000,000 and ``--rows``; quick:
142,100), fitted on their reduced representation (:mod:`tcamlab.reduction`), against the
goals of :func:`fit_goal`. The straightforward reference is the same command with the
reduction switched off (``TCAMLAB_NO_REDUCTION=1``: every row in every fit) on a log of
``--ref-fit-rows`` rows (default 100,000; quick 20,000), beside the reduced fit of that log
(reduced from that length on: ``TCAMLAB_REDUCTION_MIN_ROWS``).

The static log (``--static-rows``, default 142,100) is the joined log of a real static
test: a 1 kHz laser displacement joined with a 25 Hz thermal camera whose temperature is
held between its frames (SYNTHETIC, :func:`make_static_log`, seed 12): the temperature, a
noisy input, changes on almost every frame. ``calibrate`` and ``diagnose`` run on it reduced,
against the same commands with ``TCAMLAB_NO_REDUCTION=1`` on a log of ``--static-ref-rows``
rows (default 20,000; quick 10,000: the every-row diagnosis of the static model takes
minutes at 20,000 rows), beside the reduced fit of that log.

Nothing asserts on time; each row prints PASS or FAIL against its goal. ``--check``
(run by ``.ci/run``) measures ``validate`` and ``report`` only, at 10 million rows, and exits 1
when either fails or writes a ``report.html`` of 5 MB or more: the size goal is a property of
the code, not of the machine. Time and memory are printed against their goals but do not fail
it (they depend on the machine). With less free disk or memory than the run needs (about
2.5 GB of disk for the log and two ``predictions.csv``, 6 GB of memory) it says so and skips,
exit 0, rather than fail for the machine's sake.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
SEED = 12
RATE_HZ = 1000
PERIOD_S = 20.0
NOISE_MM = 0.005
TIME_GOAL_S = 60.0
RSS_GOAL_MB = 4000.0
HTML_GOAL_MB = 5.0
MB = 1e6
REAL_LOG_ROWS = 142_100
"""Rows of the real 1 kHz log joined with a thermal camera the fit goals name."""


def fit_goal(rows: int) -> tuple[float, float]:
    """Goal of ``calibrate`` and ``diagnose`` on a ``rows``-row log: (seconds, peak MB)."""
    if rows <= REAL_LOG_ROWS:
        return 20.0, 2000.0
    if rows <= 1_000_000:
        return 60.0, 2000.0
    return 600.0, 4000.0


def make_log(rows: int, work: Path, seed: int = SEED) -> Path:
    """Write (or reuse) a synthetic experiment of one ``rows``-row 1 kHz dynamic run.

    Returns the experiment TOML's path (``work/biglog-ROWS-sSEED/experiment.toml``).
    """
    import numpy as np
    import pandas as pd

    from tcamlab.config import load_experiment
    from tcamlab.io.csvfast import fixed_csv_bytes
    from tcamlab.kinds import dynamic

    folder = work / f"biglog-{rows}-s{seed}"
    toml = folder / "experiment.toml"
    if toml.exists():
        return toml
    folder.mkdir(parents=True, exist_ok=True)
    exp = load_experiment(REPO / "experiments" / "dynamic.toml")
    n_period = int(PERIOD_S * RATE_HZ)
    t = np.arange(n_period) / RATE_HZ
    v = np.where((t >= 0.5) & (t < 0.5 + exp.rig.pulse), exp.rig.voltage, 0.0)
    one = dynamic.predict(exp.sample, exp.rig, pd.DataFrame({"time": t, "voltage": v}))
    reps = -(-rows // n_period)
    rng = np.random.default_rng(seed)
    disp_um = np.tile(one["displacement"] * 1e6, reps)[:rows] + rng.normal(0, NOISE_MM * 1e3, rows)
    disp_mm = np.round(disp_um) / 1e3  # logged to 1 um
    disp_mm[0] = 0.0  # the log is zeroed on its first row
    frame = pd.DataFrame(
        {
            "time_s": np.arange(rows) / RATE_HZ,
            "voltage_V": np.tile(v, reps)[:rows],
            "displacement_mm": disp_mm,
        }
    )
    # fixed-point text by the numba writer of predictions.csv: pandas' float formatting
    # takes minutes for 10 million rows
    (folder / "run1.csv").write_bytes(fixed_csv_bytes(frame))
    src = (REPO / "experiments" / "dynamic.toml").read_text()
    body = src[src.index("[sample]") :]
    toml.write_text(
        'kind = "dynamic"\n'
        f'title = "Long 1 kHz log, {rows} rows (synthetic)"\n'
        'runs = ["run1.csv"]\n'
        'notes = "SYNTHETIC: bench/bench_large_log.py make_log, the thesis model tiled plus noise."\n\n'
        "[synthetic]\n"
        'generator = "bench/bench_large_log.py make_log"\n'
        f"seed = {seed}\n"
        f'command = "python bench/bench_large_log.py --rows {rows}"\n\n' + body
    )
    return toml


CAMERA_HZ = 25.0
"""Frame rate of the thermal camera of :func:`make_static_log` [Hz]."""
CAMERA_NOISE_C = 0.5
"""Sd of the camera's temperature per frame [degC]."""
OVEN_CYCLE_S = 60.0
"""Period of the heat-cool cycle of :func:`make_static_log` [s]."""


def make_static_log(
    rows: int, work: Path, seed: int = SEED, camera: str = "held", lag_s: float = 0.0
) -> Path:
    """Write (or reuse) a synthetic static experiment of one ``rows``-row log: a 1 kHz laser
    displacement joined with a 25 Hz thermal camera's temperature.

    SYNTHETIC (seed ``seed``): the actuator's temperature follows a heat-cool cycle, 25 to
    80 degC and back every 60 s; the thesis static model (``tcamlab.kinds.static.predict`` on
    the bundled ``experiments/static.toml`` sample and rig) on that temperature plus laser
    noise (sd 5 um) rounded to 1 um is the displacement; the camera reads the temperature
    every 40 ms with noise (sd 0.5 degC, rounded to 0.1 degC). ``camera`` is how its frames
    are joined to the laser's rows: ``"held"`` (each row takes the nearest frame, a staircase)
    or ``"interpolated"`` (linear between frames; the noise is then on every row, correlated
    over a frame). ``lag_s`` > 0: the actuator follows the camera's scene through a
    first-order thermal lag of that time constant [s] (the oven-thermal-lag effect).

    Returns the experiment TOML's path (``work/staticlog-ROWS-CAMERA-sSEED/experiment.toml``).
    """
    import numpy as np
    import pandas as pd

    from tcamlab.config import load_experiment
    from tcamlab.effects import Mods
    from tcamlab.io.csvfast import fixed_csv_bytes
    from tcamlab.kinds import static

    folder = work / f"staticlog-{rows}-{camera}-s{seed}" / (f"lag{lag_s:g}" if lag_s else "")
    toml = folder / "experiment.toml"
    if toml.exists():
        return toml
    folder.mkdir(parents=True, exist_ok=True)
    exp = load_experiment(REPO / "experiments" / "static.toml")
    rng = np.random.default_rng(seed)
    t = np.arange(rows) / RATE_HZ
    true_c = 25.0 + 27.5 * (1.0 - np.cos(2.0 * np.pi * t / OVEN_CYCLE_S))
    disp = static.predict(
        exp.sample, exp.rig, pd.DataFrame({"time": t, "temperature": true_c}), Mods(lag_tau=lag_s)
    )
    disp_um = disp["displacement"] * 1e6 + rng.normal(0, NOISE_MM * 1e3, rows)
    disp_mm = np.round(disp_um) / 1e3
    disp_mm[0] = 0.0  # the log is zeroed on its first row
    t_frame = np.arange(0.0, t[-1] + 1.0 / CAMERA_HZ, 1.0 / CAMERA_HZ)
    frame_c = 25.0 + 27.5 * (1.0 - np.cos(2.0 * np.pi * t_frame / OVEN_CYCLE_S))
    frame_c = np.round((frame_c + rng.normal(0, CAMERA_NOISE_C, t_frame.size)) * 10) / 10
    if camera == "held":
        temp = frame_c[np.clip(np.round(t * CAMERA_HZ).astype(int), 0, t_frame.size - 1)]
    else:
        temp = np.interp(t, t_frame, frame_c)
    frame = pd.DataFrame({"time_s": t, "temperature_C": temp, "displacement_mm": disp_mm})
    (folder / "run1.csv").write_bytes(fixed_csv_bytes(frame))
    src = (REPO / "experiments" / "static.toml").read_text()
    body = src[src.index("[sample]") :]
    toml.write_text(
        'kind = "static"\n'
        f'title = "Long 1 kHz laser log with a 25 Hz thermal camera ({camera}), {rows} rows'
        f'{f", a {lag_s:g} s thermal lag" if lag_s else ""} (synthetic)"\n'
        'runs = ["run1.csv"]\n'
        'notes = "SYNTHETIC: bench/bench_large_log.py make_static_log, the thesis static model '
        'on a heat-cool cycle, laser and camera noise."\n\n'
        "[synthetic]\n"
        'generator = "bench/bench_large_log.py make_static_log"\n'
        f"seed = {seed}\n"
        f'command = "python bench/bench_large_log.py --static-rows {rows}"\n\n' + body
    )
    return toml


def run_measured(args: list[str], env: dict | None = None) -> dict:
    """Run ``args`` from the repository root (``env`` added to the environment); wall time [s]
    and the child's peak RSS [MB] (``os.wait4``'s ``ru_maxrss``; this parent stays small, so
    nothing of it is counted)."""
    t0 = time.perf_counter()
    full_env = dict(os.environ, **(env or {}))
    proc = subprocess.Popen(args, cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, env=full_env)
    out = proc.stdout.read().decode(errors="replace")
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    return {
        "wall_s": time.perf_counter() - t0,
        "rss_mb": usage.ru_maxrss * 1024 / MB,
        # CPU time does not grow with other jobs on the machine as the wall time does
        "cpu_s": usage.ru_utime + usage.ru_stime,
        "exit": proc.returncode,
        "output": out,
    }


_READ = """
import sys, time
t0 = time.perf_counter()
if sys.argv[2] == "tcamlab":
    from tcamlab.io import read_run
    read_run(sys.argv[1], "dynamic")
else:
    import pandas
    pandas.read_csv(sys.argv[1])
print(time.perf_counter() - t0)
"""

_FIGURE = """
import sys, time
import numpy as np, pandas as pd
from tcamlab.report.figures import new_figure, figure_to_svg
rows = int(sys.argv[3])
df = pd.read_csv(sys.argv[1], nrows=rows, engine="c", dtype=float)
t0 = time.perf_counter()
fig, ax = new_figure()
ax.plot(df["time_s"], df["displacement_mm"], ".", ms=1.5, label="run1 measured")
ax.legend()
if sys.argv[2] == "plain":
    import io
    buf = io.StringIO()
    fig.savefig(buf, format="svg")
    size = len(buf.getvalue().encode())
else:
    size = len(figure_to_svg(fig).encode())
print(time.perf_counter() - t0, size)
"""


def measure(rows: int, work: Path, ref_rows: int, refs: bool = True) -> dict:
    """Every figure of the benchmark for a ``rows``-row log (see the module docstring);
    without ``refs`` only ``validate`` and ``report``."""
    py = sys.executable
    gen = f"import sys; sys.path.insert(0, 'bench'); import bench_large_log as b; from pathlib import Path; print(b.make_log({rows}, Path({str(work)!r})))"
    made = run_measured([py, "-c", gen])
    toml = Path(made["output"].strip().splitlines()[-1])
    csv = toml.parent / "run1.csv"
    res = {"rows": rows, "csv_mb": csv.stat().st_size / MB}
    for name, cmd in (
        (
            "validate",
            [py, "-m", "tcamlab", "validate", "dynamic", str(toml), "--out", str(work / "v"), "--force"],
        ),
        ("report", [py, "-m", "tcamlab", "report", str(toml), "--out", str(work / "r")]),
    ):
        r = run_measured(cmd)
        folder = work / ("v" if name == "validate" else "r") / toml.stem
        r["html_mb"] = (folder / "report.html").stat().st_size / MB if r["exit"] == 0 else None
        res[name] = r
    if not refs:
        return res
    for how in ("tcamlab", "plain"):
        r = run_measured([py, "-c", _READ, str(csv), how])
        r["call_s"] = float(r["output"].split()[-1])
        res[f"read_{how}"] = r
    for how in ("envelope", "plain"):
        r = run_measured([py, "-c", _FIGURE, str(csv), how, str(min(rows, ref_rows))])
        call, size = r["output"].split()[-2:]
        r["call_s"], r["svg_mb"] = float(call), int(size) / MB
        res[f"figure_{how}"] = r
    return res


def _log(rows: int, work: Path, maker: str = "make_log") -> Path:
    """The experiment file of a ``rows``-row log by ``maker`` (:func:`make_log` or
    :func:`make_static_log`), made in a subprocess (its memory not ours)."""
    py = sys.executable
    gen = f"import sys; sys.path.insert(0, 'bench'); import bench_large_log as b; from pathlib import Path; print(b.{maker}({rows}, Path({str(work)!r})))"
    made = run_measured([py, "-c", gen])
    return Path(made["output"].strip().splitlines()[-1])


def measure_fits(fit_rows: list[int], ref_rows: int, work: Path, maker: str = "make_log") -> dict:
    """``calibrate`` and ``diagnose`` on a log of each of ``fit_rows`` rows (reduced fits), and
    on a ``ref_rows``-row log both reduced and on every row (the reference); ``ref_rows`` 0:
    no reference. ``maker``: the log's generator (``make_log``, ``make_static_log``)."""
    py = sys.executable
    out = {}

    def both(toml: Path, env: dict) -> dict:
        return {
            "calibrate": run_measured([py, "-m", "tcamlab", "calibrate", str(toml), "--force"], env),
            "diagnose": run_measured([py, "-m", "tcamlab", "diagnose", str(toml), "--json"], env),
        }

    for rows in fit_rows:
        out[f"fit_{rows}"] = both(_log(rows, work, maker), {})
    if ref_rows:
        toml = _log(ref_rows, work, maker)
        out["ref_reduced"] = both(toml, {"TCAMLAB_REDUCTION_MIN_ROWS": str(min(ref_rows, 50_000))})
        out["ref_every_row"] = both(toml, {"TCAMLAB_NO_REDUCTION": "1"})
    return out


def print_fits(res: dict, label: str = "") -> None:
    """One line per fit measurement, PASS/FAIL against :func:`fit_goal`; ``label`` names the
    log (e.g. ``static``) at the start of each line."""
    for key, pair in res.items():
        if not key.startswith("fit_"):
            continue
        rows = int(key[4:])
        goal_s, goal_mb = fit_goal(rows)
        for name, r in pair.items():
            ok = r["exit"] == 0 and r["wall_s"] <= goal_s and r["rss_mb"] <= goal_mb
            print(
                f"{label}{name:9s} {rows:>10,} rows {r['wall_s']:7.1f} s (CPU {r['cpu_s']:.1f} s)  peak RSS "
                f"{r['rss_mb']:6.0f} MB  exit {r['exit']}  goal <= {goal_s:.0f} s, <= {goal_mb:.0f} MB: "
                + ("PASS" if ok else "FAIL")
            )
    if "ref_every_row" in res:
        for name in ("calibrate", "diagnose"):
            a, b = res["ref_reduced"][name], res["ref_every_row"][name]
            print(
                f"{label}{name:9s} reference on {res['ref_rows']:,} rows: reduced {a['wall_s']:.1f} s "
                f"({a['rss_mb']:.0f} MB, exit {a['exit']}) against every row {b['wall_s']:.1f} s "
                f"({b['rss_mb']:.0f} MB, exit {b['exit']}): {b['wall_s'] / a['wall_s']:.1f}x faster"
            )


def print_table(res: dict) -> None:
    """One line per figure, PASS/FAIL against the goals."""
    rows = res["rows"]
    print(f"SYNTHETIC 1 kHz dynamic log: {rows:,} rows, {res['csv_mb']:.0f} MB CSV (seed {SEED})")
    for name in ("validate", "report"):
        r = res[name]
        ok = r["exit"] == 0 and r["wall_s"] < TIME_GOAL_S and r["rss_mb"] < RSS_GOAL_MB
        ok = ok and r["html_mb"] is not None and r["html_mb"] < HTML_GOAL_MB
        html = "-" if r["html_mb"] is None else f"{r['html_mb']:.2f} MB"
        print(
            f"{name:9s} {r['wall_s']:7.1f} s (CPU {r['cpu_s']:.1f} s)  peak RSS {r['rss_mb']:6.0f} MB  report.html {html}  "
            f"exit {r['exit']}  goal < {TIME_GOAL_S:.0f} s, < {RSS_GOAL_MB:.0f} MB, < {HTML_GOAL_MB:.0f} MB: "
            + ("PASS" if ok else "FAIL")
        )
    if "read_plain" not in res:
        return
    a, b = res["read_tcamlab"], res["read_plain"]
    print(
        f"read      read_run {a['call_s']:.2f} s ({a['rss_mb']:.0f} MB) against pandas.read_csv "
        f"{b['call_s']:.2f} s ({b['rss_mb']:.0f} MB): ratio {a['call_s'] / b['call_s']:.2f}"
    )
    a, b = res["figure_envelope"], res["figure_plain"]
    print(
        f"figure    envelope {a['call_s']:.2f} s, {a['svg_mb']:.3f} MB SVG against full resolution "
        f"{b['call_s']:.2f} s, {b['svg_mb']:.1f} MB (first {min(rows, res['ref_rows']):,} rows): "
        f"{b['call_s'] / a['call_s']:.0f}x faster, {b['svg_mb'] / a['svg_mb']:.0f}x smaller"
    )


def check_failures(res: dict) -> list[str]:
    """What fails ``--check``: a command that exited non-zero or a report.html >= 5 MB."""
    bad = []
    for name in ("validate", "report"):
        r = res[name]
        if r["exit"] != 0:
            bad.append(f"{name} exited {r['exit']}: {r['output'].strip().splitlines()[-1:]}")
        elif r["html_mb"] >= HTML_GOAL_MB:
            bad.append(f"{name}: report.html {r['html_mb']:.2f} MB >= {HTML_GOAL_MB:.0f} MB")
    return bad


def room_for(rows: int, work: Path) -> str | None:
    """Why this machine cannot hold a ``rows``-row run (disk, memory), or None."""
    import shutil

    need_disk = 250 * rows  # bytes: the CSV (25 B/row) and two predictions.csv (~80 B/row each)
    work.mkdir(parents=True, exist_ok=True)
    free = shutil.disk_usage(work).free
    if free < need_disk:
        return f"{free / 1e9:.1f} GB free under {work}, the run needs about {need_disk / 1e9:.1f} GB"
    mem = next(
        int(line.split()[1]) * 1024
        for line in Path("/proc/meminfo").read_text().splitlines()
        if line.startswith("MemAvailable")
    )
    if mem < 600 * rows:
        return f"{mem / 1e9:.1f} GB of memory available, the run needs about {600 * rows / 1e9:.1f} GB"
    return None


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--rows", type=int, default=10_000_000)
    parser.add_argument("--quick", action="store_true", help="1,000,000 rows (CI)")
    parser.add_argument("--ref-rows", type=int, default=1_000_000, help="rows of the plain figure")
    parser.add_argument(
        "--fit-rows", type=str, default=None, help="comma-separated rows of the calibrate/diagnose logs"
    )
    parser.add_argument(
        "--ref-fit-rows", type=int, default=None, help="rows of the every-row fit reference (0: none)"
    )
    parser.add_argument(
        "--static-rows", type=int, default=REAL_LOG_ROWS, help="rows of the static laser and camera log"
    )
    parser.add_argument(
        "--static-ref-rows", type=int, default=None, help="rows of its every-row reference (0: none)"
    )
    parser.add_argument("--work", type=Path, default=Path(tempfile.gettempdir()) / "tcamlab-bench-biglog")
    parser.add_argument("--json", type=Path)
    parser.add_argument(
        "--check", action="store_true", help="validate and report only; exit 1 on a report >= 5 MB"
    )
    args = parser.parse_args(argv)
    rows = 1_000_000 if args.quick else args.rows
    if args.check:
        why = room_for(rows, args.work)
        if why:
            print(f"SKIPPED the {rows:,}-row check: {why}")
            return 0
    res = measure(rows, args.work, args.ref_rows, refs=not args.check)
    res["ref_rows"] = args.ref_rows
    print_table(res)
    if not args.check:
        default = [REAL_LOG_ROWS] if args.quick else sorted({REAL_LOG_ROWS, 1_000_000, rows})
        fit_rows = [int(x) for x in args.fit_rows.split(",")] if args.fit_rows else default
        ref = args.ref_fit_rows if args.ref_fit_rows is not None else (20_000 if args.quick else 100_000)
        fits = measure_fits(fit_rows, ref, args.work)
        fits["ref_rows"] = ref
        print_fits(fits)
        res["fits"] = fits
        # the joined laser and thermal-camera static log (a noisy input on every row)
        static_ref = (
            args.static_ref_rows if args.static_ref_rows is not None else (10_000 if args.quick else 20_000)
        )
        static = measure_fits([args.static_rows], static_ref, args.work, "make_static_log")
        static["ref_rows"] = static_ref
        print(
            f"SYNTHETIC static log, laser with a {CAMERA_HZ:.0f} Hz thermal camera held between frames (seed {SEED})"
        )
        print_fits(static, "static ")
        res["static_fits"] = static
    if args.json:
        args.json.write_text(json.dumps(res, indent=1, default=str))
    if args.check:
        import shutil

        shutil.rmtree(args.work, ignore_errors=True)  # gigabytes of CSV: never left behind
        bad = check_failures(res)
        for line in bad:
            print("FAIL " + line)
        return 1 if bad else 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
