"""Make ``dynamic_aliased.diagnosis.json``: a voltage-step diagnosis the design tests read.

Synthetic data (tcamlab's virtual rig, seed 1000): the dynamic template's three runs at one
voltage, no current logged, with a resistance that rises with temperature at 3x the noise,
diagnosed by ``tcamlab diagnose``: ``aliased``, convective-heat-loss and
resistance-temperature fit the withheld runs alike (both add a V^2 dT term to the heat
balance). Only the fields ``tcamlab.design`` reads are kept, and only the hypotheses it
weighs (the two aliases and recalibration).

Run from the repository's root: ``python tests/data/design/make_dynamic_aliased.py``.
"""

import json
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
KEEP = ("recalibration", "convective-heat-loss", "resistance-temperature")


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        sim = ["simulate", "dynamic", "--experiment", "dynamic", "--seed", "1000", "--out", tmp]
        sim += ["--effect", "resistance-temperature=3", "--name", "rt"]
        subprocess.run([sys.executable, "-m", "tcamlab", *sim], check=True, capture_output=True)
        exp = str(Path(tmp) / "experiments" / "rt.toml")
        out = subprocess.run(
            [sys.executable, "-m", "tcamlab", "diagnose", exp, "--json"], capture_output=True, text=True
        )
    d = json.loads(out.stdout)
    keep = {k: d[k] for k in ("kind", "verdict", "effect", "aliased_with")}
    keep["recalibration"] = {"stand_ins": (d.get("recalibration") or {}).get("stand_ins") or {}}
    keep["noise_floor"] = {
        "by_quantity": {
            q: {"sigma": v["sigma"], "unit": v["unit"]} for q, v in d["noise_floor"]["by_quantity"].items()
        }
    }
    fields = ("effect", "recalibrated", "recalibrated_shift", "parameters", "heldout_rmse_after_noise")
    keep["ranking"] = [{k: c[k] for k in fields if k in c} for c in d["ranking"] if c["effect"] in KEEP]
    (HERE / "dynamic_aliased.diagnosis.json").write_text(json.dumps(keep, indent=1) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
