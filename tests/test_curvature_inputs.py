"""The curvature kind's per-run rule: rows at rest, the calibration start of R0, the geometry."""

import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from tcamlab.config import load_experiment
from tcamlab.errors import ConfigError, InputError
from tcamlab.kinds import get_kind
from tcamlab.starter import check_experiment

ROOT = Path(__file__).resolve().parents[1]
KIND = get_kind("curvature")
SAMPLE = KIND.preset.build_sample()
RIG = KIND.preset.build_rig()


def _log(cable_mm) -> pd.DataFrame:
    """A camera log [SI] whose resistances rise with the pull from 10 and 20 ohm at zero pull."""
    c = np.asarray(cable_mm, float) * 1e-3
    return pd.DataFrame({"cable": c, "r1": 10.0 + 17.0 * c, "r2": 20.0 + 13.0 * c})


def _r0s(data: pd.DataFrame, rig=RIG) -> tuple[float, float]:
    ro = KIND.run_options(SAMPLE, rig.replace(initial_resistance=None), data, where="x.toml")
    return ro.options["initial_resistances"]


def test_rows_at_rest_are_the_zero_pull_wherever_the_log_puts_them():
    """A log without time need not be in pull order: R0 is read at the smallest pull, not the first row."""
    ordered = _log(np.arange(11.0))
    shuffled = ordered.iloc[[9, 7, 4, 5, 1, 6, 10, 2, 0, 8, 3]].reset_index(drop=True)
    assert _r0s(ordered) == pytest.approx((10.0, 20.0), abs=1e-12)
    assert _r0s(shuffled) == pytest.approx((10.0, 20.0), abs=1e-12)
    # two rows at zero pull, apart in the log, are both read
    twice = _log([4, 0, 8, 0, 2])
    twice.loc[3, ["r1", "r2"]] = [10.02, 20.04]
    ro = KIND.run_options(SAMPLE, RIG.replace(initial_resistance=None), twice)
    assert ro.options["initial_resistances"] == pytest.approx((10.01, 20.02), abs=1e-12)
    assert ro.info["initial_resistances_source"] == "mean of the 2 rows at rest"


def test_a_log_with_no_row_at_rest_is_refused_with_a_hint_that_works():
    data = _log([3, 1, 2, 4, 5])
    with pytest.raises(
        InputError, match=r"x\.toml: curvature run: no row at rest.*1 mm \(data row 2\)"
    ) as exc:
        _r0s(data)
    assert "initial_resistance_ohm" in exc.value.hint
    # following the hint: a stated R0, or a row at zero pull
    assert (
        KIND.run_options(SAMPLE, RIG.replace(initial_resistance=10.0), data).options["initial_resistance"]
        == 10.0
    )
    assert _r0s(_log([3, 1, 2, 0, 5])) == pytest.approx((10.0, 20.0), abs=1e-12)


def test_an_unstated_r0_starts_calibration_from_the_rows_at_rest(tmp_path):
    """calibrate and diagnose refused a curvature file without R0 ("calibration needs a start
    value of initial_resistance"); it starts from the kind's rule on all runs, as documented."""
    from tcamlab.calibration import calibrate

    text = (ROOT / "experiments" / "curvature.toml").read_text(encoding="utf-8")
    # no preset either: it states R0
    text = re.sub(r"(?m)^(initial_resistance_ohm|preset)\s*=.*$", "", text).replace(
        '"../raw/', f'"{ROOT}/raw/'
    )
    path = tmp_path / "bend.toml"
    path.write_text(text, encoding="utf-8")
    exp = load_experiment(path)
    assert exp.rig.initial_resistance is None
    r0 = next(p for p in calibrate(path, params="initial_resistance").parameters)
    rest = [
        r.data.loc[r.data["cable"] == r.data["cable"].min(), ["r1", "r2"]].to_numpy() for r in exp.read_runs()
    ]
    assert r0.stated == pytest.approx(np.mean([x.mean() for x in rest]), rel=1e-12)
    assert not r0.stated_in_file and r0.value == pytest.approx(10.0, rel=0.01)
    # the one R0 is an option predict takes, alone or beside the pair (which wins)
    data = exp.read_runs()[0].data
    opts = KIND.run_options(exp.sample, exp.rig, data).options
    pair = {k: v for k, v in opts.items() if k != "initial_resistance"}
    both, paired = (KIND.predict(exp.sample, exp.rig, data, **o) for o in (opts, pair))
    np.testing.assert_allclose(both["kappa1"], paired["kappa1"], rtol=1e-12)
    r = float(opts["initial_resistance"])
    alone = KIND.predict(
        exp.sample, exp.rig, data, **{**pair, "initial_resistances": None, "initial_resistance": r}
    )
    same = KIND.predict(exp.sample, exp.rig, data, **{**pair, "initial_resistances": (r, r)})
    np.testing.assert_allclose(alone["kappa2"], same["kappa2"], rtol=1e-12)


def _example(hint: str, key: str) -> float:
    return float(re.search(rf"{key} = ([-+0-9.e]+)", hint).group(1)) * 1e-3


@pytest.mark.parametrize("d1_mm", [1e-6, 0.3, 30.0, 1e9])
def test_an_implausible_sensor_offset_is_refused_naming_the_key(d1_mm):
    """d1 lies between the sensor coil's radius (0.4 mm) and the shortest segment (30 mm)."""
    rig = RIG.replace(sensor_offset=d1_mm * 1e-3)
    with pytest.raises(
        ConfigError, match=r"x\.toml: rig\.sensor_offset_mm = .* is outside 0\.4 to 30 mm"
    ) as exc:
        KIND.run_options(SAMPLE, rig, _log(np.arange(11.0)), where="x.toml")
    fixed = rig.replace(sensor_offset=_example(exc.value.hint, "sensor_offset_mm"))
    KIND.run_options(SAMPLE, fixed, _log(np.arange(11.0)))
    for ok_mm in (0.5, 9.0, 29.0):
        KIND.run_options(SAMPLE, RIG.replace(sensor_offset=ok_mm * 1e-3), _log(np.arange(11.0)))


@pytest.mark.parametrize(
    "lengths_mm, words",
    [([60.0], "1 segment"), ([20.0, 20.0, 20.0], "3 segment"), ([300.0, 300.0], "sum to 600 mm")],
)
def test_segment_lengths_that_do_not_fit_the_log_or_the_sensor_are_refused(lengths_mm, words):
    rig = RIG.replace(segment_lengths=tuple(x * 1e-3 for x in lengths_mm))
    with pytest.raises(ConfigError, match=rf"x\.toml: rig\.segment_lengths_mm = .*{words}") as exc:
        KIND.run_options(SAMPLE, rig, _log(np.arange(11.0)), where="x.toml")
    hinted = re.search(r"segment_lengths_mm = \[([0-9.]+), ([0-9.]+)\]", exc.value.hint).groups()
    KIND.run_options(
        SAMPLE, rig.replace(segment_lengths=tuple(float(x) * 1e-3 for x in hinted)), _log([0, 1])
    )


def _variant(tmp_path: Path, old: str, new: str) -> Path:
    text = (ROOT / "experiments" / "curvature.toml").read_text()
    raw = (ROOT / "raw").as_posix()
    text = text.replace('"../raw/', f'"{raw}/')
    assert old in text
    path = tmp_path / "bend.toml"
    path.write_text(text.replace(old, new))
    return path


@pytest.mark.parametrize(
    "old, new, words",
    [
        ("segment_lengths_mm = [30.0, 30.0]", "segment_lengths_mm = [60.0]", "1 segment"),
        ("segment_lengths_mm = [30.0, 30.0]", "segment_lengths_mm = [20.0, 20.0, 20.0]", "3 segment"),
        ("segment_lengths_mm = [30.0, 30.0]", "segment_lengths_mm = [300.0, 300.0]", "sum to 600 mm"),
        ("sensor_offset_mm = 9.0", "sensor_offset_mm = 1e-6", "sensor_offset_mm"),
    ],
)
def test_check_reports_what_validate_would_refuse(tmp_path, old, new, words):
    report = check_experiment(_variant(tmp_path, old, new))
    assert len(report.problems) == 1 and words in report.problems[0], report.problems
    assert not check_experiment(_variant(tmp_path, old, old)).problems


def test_init_names_the_curvature_columns_whole(tmp_path):
    """Its [columns] comments read "read as kappa1", not "read as kappa1_per"."""
    from tcamlab.starter import write_starter

    res = write_starter("curvature", ROOT / "raw" / "curvature_run1.csv", tmp_path / "c.toml")
    text = res.path.read_text(encoding="utf-8")
    assert "# read as kappa1\n" in text and "read as kappa1_per" not in text
