#!/usr/bin/env bash
# Regenerate the shipped sample data from the simulation templates:
#   experiments/{static,dynamic,sensing,curvature}.toml
#   raw/{kind}_run{1,2,3}.csv
#   truth/{kind}.truth.json   (the generator's truth: no effects, per-run sample scatter)
# The data are effect-free virtual-rig runs (tcamlab/rig.py), 3 runs each, seed 1.
# Re-running gives byte-identical files.
set -euo pipefail
cd "$(dirname "$0")/.."

KINDS="static dynamic sensing curvature"
SEED=1

if tcamlab simulate --help >/dev/null 2>&1; then
    for kind in $KINDS; do
        tcamlab simulate "$kind" --experiment "experiments/templates/$kind.toml" --seed "$SEED" --out .
    done
else
    # The CLI is not installed yet: call the library with the same arguments
    # (and the same recorded command line), which writes the same bytes.
    for kind in $KINDS; do
        python -c "import sys; from tcamlab.rig import simulate; simulate(sys.argv[1], sys.argv[2], seed=int(sys.argv[3]), out_dir='.')" \
            "$kind" "experiments/templates/$kind.toml" "$SEED"
    done
fi
