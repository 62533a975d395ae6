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
