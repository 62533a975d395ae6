#!/usr/bin/env python
"""Startup time of ``tcamlab --help``.

Median wall time of 5 subprocess runs of ``python -m tcamlab --help`` against
the median of 5 runs of ``python -c pass`` (interpreter start-up baseline).
The difference is what importing tcamlab's CLI costs before it can print help
(heavy imports such as numba, scipy or matplotlib show up here).

    python bench/bench_cli_help.py [--runs 5] [--json out.json] [--quick]

If the CLI does not exist yet (non-zero exit), prints "CLI not available"
and exits 0 (1 with ``--quick``, the CI smoke run: one timed run each).
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time


def run_times(cmd, runs):
    times = []
    proc = None
    for _ in range(runs):
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, capture_output=True, text=True)
        times.append(time.perf_counter() - t0)
        if proc.returncode != 0:
            break
    return times, proc


def main(argv=None):
    ap = argparse.ArgumentParser(description="tcamlab --help startup time")
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--json", metavar="PATH")
    ap.add_argument(
        "--quick", action="store_true", help="CI smoke run: one timed run each; exit 1 if the CLI fails"
    )
    args = ap.parse_args(argv)
    if args.quick:
        args.runs = 1
    missing = 1 if args.quick else 0

    cli = [sys.executable, "-m", "tcamlab", "--help"]
    base = [sys.executable, "-c", "pass"]
    # One untimed run of each warms the OS file cache and .pyc files.
    warm = subprocess.run(cli, capture_output=True, text=True)
    if warm.returncode != 0:
        last = (warm.stderr.strip().splitlines() or ["(no output)"])[-1]
        print(f"CLI not available: `python -m tcamlab --help` exited {warm.returncode}: {last}")
        return missing
    subprocess.run(base, capture_output=True)
    cli_t, proc = run_times(cli, args.runs)
    if proc.returncode != 0:
        print(f"CLI not available: `python -m tcamlab --help` exited {proc.returncode}")
        return missing
    base_t, _ = run_times(base, args.runs)
    cli_med, base_med = statistics.median(cli_t), statistics.median(base_t)
    print(f"| Command | Median of {args.runs} | Min | Max |")
    print("|---|---|---|---|")
    print(
        f"| python -m tcamlab --help | {cli_med * 1e3:.0f} ms | {min(cli_t) * 1e3:.0f} ms "
        f"| {max(cli_t) * 1e3:.0f} ms |"
    )
    print(
        f"| python -c pass (baseline) | {base_med * 1e3:.0f} ms | {min(base_t) * 1e3:.0f} ms "
        f"| {max(base_t) * 1e3:.0f} ms |"
    )
    print(f"\nCLI overhead over the bare interpreter: {(cli_med - base_med) * 1e3:.0f} ms")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(
                {
                    "cli_s": cli_t,
                    "baseline_s": base_t,
                    "cli_median_s": cli_med,
                    "baseline_median_s": base_med,
                    "overhead_s": cli_med - base_med,
                },
                fh,
                indent=2,
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
