"""Off-design sweep of the gap diagnosis: other samples, noise levels and strengths.

The withheld-effect benchmark (``tcamlab benchmark diagnose``) uses the
repository's templates, the nominal noise and strengths 1, 3, 10. The
diagnosis must also hold on data it was not developed on, so this sweep
changes what the benchmark keeps fixed:

* sample and rig: each kind's template with other values (a heavier and a
  lighter load, a thicker coil, another spring constant and R0, another
  sensor offset), written to temporary template files;
* measurement noise: 0.5x and 2x the nominal instrument noise;
* strengths: 2x and 6x the noise RMS (between and beside the benchmark's).

All data is synthetic (``tcamlab.rig.simulate``, seeds 7000+). It prints the
benchmark's tables (markdown) and writes ``benchmark.json`` to ``--out``.

Run: ``python scripts/robustness_sweep.py --out bench/results/robustness``
(about 6 minutes on 2 cores).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from tcamlab.benchmark import BenchmarkResult, execute_tasks, markdown, score
from tcamlab.effects import effects_for
from tcamlab.templates import TEMPLATES

# kind -> list of (label, text appended to the template's [sample] / [rig] tables)
VARIANTS: dict[str, list[tuple[str, dict, dict]]] = {
    "static": [
        ("load 30 g, coil 0.40 mm, 140 turns", {"coil_diameter_mm": 0.40, "twists": 140.0}, {"load_g": 30.0}),
        ("load 70 g, ambient 25 C", {}, {"load_g": 70.0, "ambient_C": 25.0}),
    ],
    "dynamic": [
        ("load 70 g, 8 V, R 35 ohm", {}, {"load_g": 70.0, "voltage_V": 8.0, "resistance_ohm": 35.0}),
        ("load 30 g, pulse 2 s", {}, {"load_g": 30.0, "pulse_s": 2.0}),
    ],
    "sensing": [
        ("S 3.5 N/m, R0 45 ohm", {}, {"spring_constant_N_per_m": 3.5, "initial_resistance_ohm": 45.0}),
        ("S 6.5 N/m, R0 25 ohm", {}, {"spring_constant_N_per_m": 6.5, "initial_resistance_ohm": 25.0}),
    ],
    "curvature": [
        ("offset 7 mm, S 12 N/m", {}, {"sensor_offset_mm": 7.0, "spring_constant_N_per_m": 12.0}),
        ("offset 11 mm, R0 14 ohm", {}, {"sensor_offset_mm": 11.0, "initial_resistance_ohm": 14.0}),
    ],
}
NOISE = (0.5, 2.0)
STRENGTHS = (2.0, 6.0)


def _variant_template(kind: str, sample: dict, rig: dict, path: Path) -> Path:
    """The kind's template with some [sample] / [rig] values replaced."""
    import tomllib

    base = tomllib.loads((TEMPLATES / f"{kind}.toml").read_text())
    lines = [
        f'kind = "{kind}"',
        f'title = "{base.get("title", kind)} (variant)"',
        "runs = []",
        "",
        "[sample]",
    ]
    for k, v in {**base.get("sample", {}), **sample}.items():
        lines.append(f"{k} = {v!r}".replace("'", '"'))
    lines += ["", "[rig]"]
    rig_all = {k: v for k, v in base.get("rig", {}).items() if not isinstance(v, dict)}
    for k, v in {**rig_all, **rig}.items():
        lines.append(f"{k} = {v!r}".replace("'", '"'))
    unc = base.get("rig", {}).get("uncertainty")
    if unc:
        lines += ["", "[rig.uncertainty]"] + [f"{k} = {v!r}" for k, v in unc.items()]
    path.write_text("\n".join(lines) + "\n")
    return path


def make_tasks(tmp: Path, kinds) -> list[dict]:
    tasks = []
    seed = 7000
    for kind in kinds:
        for j, (label, sample, rig) in enumerate(VARIANTS[kind]):
            tpl = _variant_template(kind, sample, rig, tmp / f"{kind}_{j}.toml")
            noise = NOISE[j % len(NOISE)]
            for eff in effects_for(kind):
                for s in STRENGTHS:
                    seed += 1
                    tasks.append(
                        {
                            "case": "single",
                            "kind": kind,
                            "effects": {eff.name: s},
                            "seed": seed,
                            "template": str(tpl),
                            "noise_scale": noise,
                            "variant": label,
                        }
                    )
            for _ in range(2):
                seed += 1
                tasks.append(
                    {
                        "case": "null",
                        "kind": kind,
                        "effects": {},
                        "seed": seed,
                        "template": str(tpl),
                        "noise_scale": noise,
                        "variant": label,
                    }
                )
    return tasks


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="bench/results/robustness")
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--kind", action="append", default=None)
    args = ap.parse_args(argv)
    kinds = args.kind or list(VARIANTS)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="tcam-sweep-") as tmp:
        tasks = make_tasks(Path(tmp), kinds)
        results = execute_tasks(tasks, None, args.workers)
    wall = time.perf_counter() - t0
    for r in results:
        r.pop("template", None)
    res = BenchmarkResult(
        scores=score(results),
        results=results,
        settings={
            "generator": "tcamlab.rig (off-design variants)",
            "n_tasks": len(tasks),
            "quick": False,
            "wall_seconds": wall,
            "noise_scales": list(NOISE),
            "strengths": list(STRENGTHS),
        },
    )
    import json

    (out / "benchmark.json").write_text(json.dumps(res.to_dict(), indent=1))
    (out / "benchmark.md").write_text(markdown(res))
    print(markdown(res))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
