import shutil
from pathlib import Path

import numpy as np
import pytest

from tcamlab.params import THESIS_ROBOT, THESIS_TCA, THESIS_TCS, THESIS_TCS_SPRING_CONSTANT


@pytest.fixture
def tca():
    return THESIS_TCA.build_sample(), THESIS_TCA.build_rig()


@pytest.fixture
def tcs():
    return THESIS_TCS.build_sample(), THESIS_TCS.build_rig(spring_constant=THESIS_TCS_SPRING_CONSTANT.value)


@pytest.fixture
def robot():
    return THESIS_ROBOT.build_sample(), THESIS_ROBOT.build_rig()


def geometry(sample):
    """The sample's keyword arguments without the thermal ones (sensing models)."""
    return sample.sensor_kwargs()


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture
def lab(tmp_path):
    """A copy of the shipped experiments (without templates) and raw logs.

    test_config.py overrides it with its own one-run tree.
    """
    shutil.copytree(
        ROOT / "experiments", tmp_path / "experiments", ignore=shutil.ignore_patterns("templates")
    )
    shutil.copytree(ROOT / "raw", tmp_path / "raw")
    return tmp_path


@pytest.fixture
def log_the_current():
    """A function rewriting a simulation's runs with a logged current (below)."""
    return _log_the_current


def _log_the_current(sim, seed, runs=None):
    """The simulated runs (those indexed in ``runs``, default all) rewritten with a current_A
    column: the model's current under the rig's true effects plus 0.5 mA of white noise
    (SYNTHETIC, numpy seed ``seed``), as a sense resistor beside the laser would log it. The
    rig's comment lines are kept."""
    from io import StringIO

    import pandas as pd

    from tcamlab.config import load_experiment
    from tcamlab.effects import Mods
    from tcamlab.kinds import predict

    exp = load_experiment(sim.experiment_path)
    mods = Mods(**sim.truth["mods"])
    rng = np.random.default_rng(seed)
    for j, path in enumerate(sim.run_paths):
        if runs is not None and j not in runs:
            continue
        lines = path.read_text().splitlines(keepends=True)
        raw = pd.read_csv(StringIO("".join(x for x in lines if not x.startswith("#"))))
        frame = pd.DataFrame({"time": raw["time_s"], "voltage": raw["voltage_V"]})
        current = predict("dynamic", exp.sample, exp.rig, frame, mods)["current"]
        raw.insert(2, "current_A", np.round(current + rng.normal(0.0, 0.5e-3, current.size), 5))
        path.write_text("".join(x for x in lines if x.startswith("#")) + raw.to_csv(index=False))
    return load_experiment(sim.experiment_path)
