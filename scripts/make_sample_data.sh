#!/usr/bin/env bash
# Regenerate the shipped sample data from the simulation templates shipped in
# the package (tcamlab/templates/KIND.toml, named by their kind):
#   experiments/{static,dynamic,sensing,curvature}.toml
#   raw/{kind}_run{1,2,3}.csv
#   truth/{kind}.truth.json   (the generator's truth: no effects, per-run sample scatter)
# The data are effect-free virtual-rig runs (tcamlab/rig/), 3 runs each, seed 1.
# Re-running gives byte-identical files: each records this command line, which
# tests/test_real_files.py re-runs and compares with the shipped files.
set -euo pipefail
cd "$(dirname "$0")/.."

KINDS=$(python -c "from tcamlab.kinds import KINDS; print(' '.join(KINDS))")
SEED=1

if tcamlab simulate --help >/dev/null 2>&1; then
    for kind in $KINDS; do
        tcamlab simulate "$kind" --experiment "$kind" --seed "$SEED" --out . --force
    done
else
    # The CLI is not installed yet: call the library with the same arguments
    # (and the same recorded command line), which writes the same bytes.
    for kind in $KINDS; do
        python -c "import sys; from tcamlab.pipeline import simulate_experiment; simulate_experiment(sys.argv[1], sys.argv[2], seed=int(sys.argv[3]), out_dir='.', force=True)" \
            "$kind" "$kind" "$SEED"
    done
fi
