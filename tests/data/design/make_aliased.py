"""Make ``static_aliased.diagnosis.json``: a diagnosis the design tests read.

Synthetic data (tcamlab's virtual rig, seed 1): the static template's three heating runs at
one load with a temperature-dependent Young's modulus at 3x the noise, diagnosed by
``tcamlab diagnose``; recalibration, youngs-modulus-temperature and shear-modulus-temperature
fit the withheld runs alike. Only the fields ``tcamlab.design`` reads are kept.

Run from the repository's root: ``python tests/data/design/make_aliased.py``.
"""

import json
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
KEEP = ("recalibration", "youngs-modulus-temperature", "shear-modulus-temperature")


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        sim = ["simulate", "static", "--experiment", "static", "--seed", "1", "--out", tmp]
        sim += ["--effect", "youngs-modulus-temperature=3", "--name", "aliased"]
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
    keep["ranking"] = [{k: c[k] for k in fields} for c in d["ranking"] if c["effect"] in KEEP]
    (HERE / "static_aliased.diagnosis.json").write_text(json.dumps(keep, indent=1) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
