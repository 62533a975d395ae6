"""Make the static diagnoses the design tests read (only the fields ``tcamlab.design`` reads).

Synthetic data (tcamlab's virtual rig), the static template's three heating runs at one load,
diagnosed by ``tcamlab diagnose``:

- ``static_aliased.diagnosis.json`` (seed 1): a temperature-dependent Young's modulus at 3x
  the noise; recalibration, youngs-modulus-temperature and shear-modulus-temperature fit the
  withheld runs alike.
- ``static_drift.diagnosis.json`` (seed 6): a laser drifting at 3x the noise; `miscalibrated`,
  with the drift fitted near zero and a wide interval beside E(T) and G(T).

Run from the repository's root: ``python tests/data/design/make_aliased.py [aliased|drift]``
(both without an argument).
"""

import json
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
TEMPERATURE = ("recalibration", "youngs-modulus-temperature", "shear-modulus-temperature")
CASES = {
    # name: (seed, the effect simulated at 3x, the ranking's entries kept)
    "aliased": (1, "youngs-modulus-temperature", TEMPERATURE),
    "drift": (6, "displacement-drift", (*TEMPERATURE, "displacement-drift")),
}


def make(name: str) -> None:
    seed, effect, keep_effects = CASES[name]
    with tempfile.TemporaryDirectory() as tmp:
        sim = ["simulate", "static", "--experiment", "static", "--seed", str(seed), "--out", tmp]
        sim += ["--effect", f"{effect}=3", "--name", "aliased"]
        subprocess.run([sys.executable, "-m", "tcamlab", *sim], check=True, capture_output=True)
        exp = str(Path(tmp) / "experiments" / "aliased.toml")
        out = subprocess.run(
            [sys.executable, "-m", "tcamlab", "diagnose", exp, "--json"], capture_output=True, text=True
        )
    d = json.loads(out.stdout)
    keep = {k: d[k] for k in ("kind", "verdict", "effect", "aliased_with")}
    keep["recalibration"] = {"stand_ins": d["recalibration"]["stand_ins"]}
    keep["noise_floor"] = {
        "by_quantity": {
            q: {"sigma": v["sigma"], "unit": v["unit"]} for q, v in d["noise_floor"]["by_quantity"].items()
        }
    }
    fields = ("effect", "recalibrated", "recalibrated_shift", "parameters")
    keep["ranking"] = [{k: c[k] for k in fields} for c in d["ranking"] if c["effect"] in keep_effects]
    (HERE / f"static_{name}.diagnosis.json").write_text(json.dumps(keep, indent=1) + "\n", encoding="utf-8")


if __name__ == "__main__":
    for name in sys.argv[1:] or list(CASES):
        make(name)
