"""The self-sensing powered run's protocol options and menu: the default program unchanged, the
[protocol] table read and refused, each menu entry within the sample's limits, a protocol file
through the virtual rig, and the design ranking the menu on a diagnosis."""

from __future__ import annotations

import hashlib
import json

import numpy as np
import pandas as pd
import pytest

from tcamlab.config import load_experiment
from tcamlab.design import design, protocol_toml
from tcamlab.design.hypotheses import hypotheses
from tcamlab.design.protocols import cost_minutes, kind_module, protocol_frames
from tcamlab.design.toml import KEY_DOCS
from tcamlab.errors import ConfigError
from tcamlab.kinds import get_kind
from tcamlab.kinds import selfsensing as ss
from tcamlab.kinds import selfsensing_protocol as sp
from tcamlab.kinds.static import G_LIMIT_MARGIN_C, MAX_OVEN_C
from tcamlab.rig import simulate
from tcamlab.rig.selfsensing import powered_run
from tcamlab.templates import TEMPLATES

DEFAULT_DIGEST = "41e2922e222f7abd772d6033cfc9b26ea4279448196ac16049622164d9f46ca4"
"""sha256 of each column's name and bytes of the program before it took options (seed 0)."""


# A diagnosis as tcamlab diagnose wrote it (only the fields design reads, and only the fits of
# the named effect and one rival):
#   tcamlab simulate selfsensing --experiment selfsensing --out A --seed 1 --runs 5 --effect coating-tcr=3
#   tcamlab diagnose A/experiments/selfsensing.toml --json
# attributed to resistance-drift (its ranking's second to fourth: inter-coil-contact,
# recalibration, coating-tcr).
SELFSENSING_ATTRIBUTED = json.loads(
    '{"kind":"selfsensing","verdict":"attributed","effect":"resistance-drift","aliased_with":[],"reca'
    'libration":{"stand_ins":{}},"noise_floor":{"by_quantity":{"displacement":{"sigma":0.112591219071'
    '66951,"unit":"mm"}}},"ranking":[{"effect":"resistance-drift","recalibrated":{"damping":{"ci95":['
    '0.6348616092191005,1.1114233240027065],"prior_sd":0.12,"unit":"N s/m","value":0.84},"heat_loss":'
    '{"ci95":[0.006953149580256474,0.00856819923315508],"prior_sd":0.01615,"unit":"W/K","value":0.007'
    '7185472014859174},"initial_resistance":{"ci95":[22.67950769259802,22.78445922293515],"prior_sd":'
    '0.24,"unit":"ohm","value":22.731922888709693},"tcr":{"ci95":[0.003221948837009682,0.003924039212'
    '806669],"prior_sd":0.0002,"unit":"1/K","value":0.0035557071839625426},"thermal_mass":{"ci95":[0.'
    '020563830179918068,0.02535136596673202],"prior_sd":0.00845,"unit":"J/K","value":0.02283245901274'
    '8312}},"recalibrated_shift":{"covariance":[[1.3872293157870386e-06,3.343366772206766e-06,3.81754'
    "4967726798e-06,3.700633810259254e-06,0.0],[3.34336677220699e-06,0.0025291341806164764,0.00268478"
    "1211094682,0.0026793140034554117,0.0],[3.8175449677270326e-06,0.0026847812110946797,0.0028508719"
    "124280277,0.002844348298390121,0.0],[3.700633810259492e-06,0.0026793140034554117,0.0028443482983"
    '90123,0.002839005507159367,0.0],[0.0,0.0,0.0,0.0,0.02040816326530612]],"joint_covariance":[[1.38'
    "72293157870386e-06,3.343366772206766e-06,3.817544967726798e-06,3.700633810259254e-06,0.0,2.61263"
    "8983870368e-09],[3.34336677220699e-06,0.0025291341806164764,0.002684781211094682,0.0026793140034"
    "554117,0.0,9.27808055472775e-09],[3.8175449677270326e-06,0.0026847812110946797,0.002850871912428"
    "0277,0.002844348298390121,0.0,1.0017427419801708e-08],[3.700633810259492e-06,0.00267931400345541"
    "17,0.002844348298390123,0.002839005507159367,0.0,1.092305045680085e-08],[0.0,0.0,0.0,0.0,0.02040"
    "816326530612,0.0],[2.6126389838703704e-09,9.278080554727998e-09,1.0017427419801981e-08,1.0923050"
    '456801112e-08,0.0,8.224798316408854e-12]],"u":[-0.054283599110021896,-0.06644709668866078,-0.152'
    '728051333201,-0.1457902348970146,0.0]},"parameters":{"r0_drift":{"ci95":[-0.00010436844961055869'
    ',-9.31265237895974e-05],"stderr":2.8678909178015914e-06,"unit":"1/s","value":-9.874748670007805e'
    '-05}},"heldout_rmse_after_noise":0.9920406955626265},{"effect":"coating-tcr","recalibrated":{"da'
    'mping":{"ci95":[0.6321186413727692,1.1162461503550214],"prior_sd":0.12,"unit":"N s/m","value":0.'
    '84},"heat_loss":{"ci95":[0.00737505105413968,0.017433419948363407],"prior_sd":0.01615,"unit":"W/'
    'K","value":0.011338975357916486},"initial_resistance":{"ci95":[23.407556089609653,23.47526753169'
    '7998],"prior_sd":0.24,"unit":"ohm","value":23.441387362244864},"tcr":{"ci95":[0.0035074216686175'
    '34,0.004324876843897544],"prior_sd":0.0002,"unit":"1/K","value":0.003894761450511245},"thermal_m'
    'ass":{"ci95":[0.021557309701837266,0.05103335856829547],"prior_sd":0.00845,"unit":"J/K","value":'
    '0.03316838729546035}},"recalibrated_shift":{"covariance":[[5.430014986691467e-07,5.0166529729640'
    "84e-09,2.4930300855847342e-06,2.106125530967107e-06,0.0],[5.016652978327459e-09,0.00285642021867"
    "4574,4.274955348552845e-06,4.279651807348352e-06,0.0],[2.4930300855885793e-06,4.274955256350098e"
    "-06,0.04833047664878716,0.048247068869409986,0.0],[2.106125530970944e-06,4.279651715303677e-06,0"
    '.04824706886940996,0.04816480047719852,0.0],[0.0,0.0,0.0,0.0,0.02104424149823711]],"joint_covari'
    'ance":[[5.430014986691467e-07,5.016652972964084e-09,2.4930300855847342e-06,2.106125530967107e-06'
    ",0.0,1.1106046555066302e-08],[5.016652978327459e-09,0.002856420218674574,4.274955348552845e-06,4"
    ".279651807348352e-06,0.0,-1.1100806894336968e-05],[2.4930300855885793e-06,4.274955256350098e-06,"
    "0.04833047664878716,0.048247068869409986,0.0,0.0002347315801758851],[2.106125530970944e-06,4.279"
    "651715303677e-06,0.04824706886940996,0.04816480047719852,0.0,0.000234329780727786],[0.0,0.0,0.0,"
    "0.0,0.02104424149823711,0.0],[1.1106046555064088e-08,-1.1100806894784814e-05,0.00023473158017552"
    '596,0.0002343297807274276,0.0,1.1833660730887289e-06]],"u":[-0.023550679581581857,0.024631365659'
    '937288,0.22068601661823983,0.2388295428840541,0.0]},"parameters":{"tcr_extra":{"ci95":[-0.000963'
    '5225732026653,0.0033006781911032864],"stderr":0.0010878263064886457,"unit":"1/K","value":0.00116'
    '85778089503107}},"heldout_rmse_after_noise":1.7197223312701142}]}'
)


def template():
    return load_experiment(TEMPLATES / "selfsensing.toml", require_runs=False)


def digest(frame: pd.DataFrame) -> str:
    h = hashlib.sha256()
    for c in frame.columns:
        h.update(c.encode())
        h.update(np.ascontiguousarray(frame[c].to_numpy()).tobytes())
    return h.hexdigest()


def test_the_default_program_is_byte_identical():
    rig = template().rig
    assert digest(sp.protocol(rig, np.random.default_rng(0))) == DEFAULT_DIGEST
    # the kind's names still lead to it
    assert digest(get_kind("selfsensing").protocol(rig, np.random.default_rng(0))) == DEFAULT_DIGEST
    assert ss.protocol is sp.protocol and ss.PROBE_V == sp.PROBE_V and kind_module("selfsensing") is sp
    # an empty table, and the menu's repeat, read back to the same program
    (opts,) = sp.protocol_runs({}, rig)
    assert digest(sp.protocol(rig, np.random.default_rng(0), **opts)) == DEFAULT_DIGEST
    exp = template()
    repeat = dict(sp.design_menu(exp.sample, exp.rig))["repeat (same protocol)"]
    frames = protocol_frames("selfsensing", exp.rig, repeat)
    assert len(frames) == 2 and digest(frames[0]) == DEFAULT_DIGEST


def test_the_options_shape_the_program():
    rig = template().rig
    table = {
        "probe_V": [2.0],
        "rider_g": 10.0,
        "rider_s": 20.0,
        "hold_s": 10.0,
        "ripple_V": 0.5,
        "steps_s": 24.0,
    }
    (opts,) = sp.protocol_runs(table, rig)
    f = sp.protocol(rig, np.random.default_rng(3), **opts)
    t, v, m = (f[c].to_numpy() for c in ("time", "voltage", "load_mass"))
    assert t[-1] == pytest.approx(2 + 24 + 12 + 12 + 12 + 10 - 0.01)
    assert np.all(v[t < 2.0] == 2.0)  # the rest stays plain: its rows set R0
    # the steps are 6 s on each level; between them the probe +- the ripple
    assert np.all(v[(t >= 2.0) & (t < 8.0)] == 4.0) and np.all(v[(t >= 14.0) & (t < 20.0)] == 6.0)
    assert set(np.unique(v[(t >= 8.0) & (t < 14.0)])) == {1.5, 2.5}
    assert np.all(np.isin(v[t >= 62.0], [1.5, 2.5]))  # the hold, after the chirp
    assert np.all(m[t < 20.0] == rig.load) and np.all(m[t >= 20.0] == pytest.approx(rig.load + 0.01))
    # runs cycle through the probe voltages
    runs = sp.protocol_runs({"probe_V": [1.5, 2.5], "runs": 3}, rig)
    assert [r["probe_v"] for r in runs] == [1.5, 2.5, 1.5]


@pytest.mark.parametrize(
    ("table", "key"),
    [
        ({"probe_volts": [2.0]}, "probe_volts"),
        ({"load_logged": False}, "load_logged"),
        ({"probe_V": 1.5}, "probe_V"),
        ({"probe_V": [0.1]}, "probe_V"),
        ({"probe_V": [4.0]}, "probe_V"),
        ({"rider_g": -50.0}, "rider_g"),
        ({"rider_g": "5"}, "rider_g"),
        ({"rider_s": [35.0, 15.0]}, "rider_s"),
        ({"rider_s": 1.0}, "rider_s"),
        ({"rider_s": 80.0}, "rider_s"),
        ({"rest_s": 0.0}, "rest_s"),
        ({"chirp_s": -1.0}, "chirp_s"),
        ({"hold_s": float("nan")}, "hold_s"),
        ({"ripple_V": 1.2}, "ripple_V"),
        ({"ripple_Hz": 0.0}, "ripple_Hz"),
        ({"runs": 0}, "runs"),
        ({"runs": True}, "runs"),
    ],
)
def test_bad_keys_and_values_are_refused_naming_the_key(table, key):
    with pytest.raises(ConfigError, match=key) as err:
        sp.protocol_runs(table, template().rig)
    assert err.value.hint and "\n" not in str(err.value)


def test_every_menu_entry_stays_within_the_samples_limits():
    exp = template()
    menu = sp.design_menu(exp.sample, exp.rig)
    names = [n for n, _ in menu]
    assert names[0] == "repeat (same protocol)" and len(set(names)) == len(names) == 7
    assert any(n.startswith("second probe voltage") for n in names)
    assert any(n.startswith("load step") for n in names)
    for name, table in menu:
        assert table["kind"] == "selfsensing" and set(table) <= set(sp.PROTOCOL_KEYS) <= set(KEY_DOCS)
        assert sp.program_limit(exp.sample, exp.rig, table) is None, name
        frames = protocol_frames("selfsensing", exp.rig, table)
        assert len(frames) == table["runs"] and cost_minutes(frames, "selfsensing") > 0
        for f in frames:
            v, m = f["voltage"].to_numpy(), f["load_mass"].to_numpy()
            assert 0.0 <= v.min() and v.max() <= sp.DRIVER_MAX_V and m.min() > 0.0, name
        f = frames[-1].iloc[::10]  # the hottest run: the second probe's is the last
        run = powered_run(exp.sample, exp.rig, f["time"], f["voltage"], f["load_mass"])
        assert run.temperature.max() < MAX_OVEN_C - G_LIMIT_MARGIN_C, name


def test_a_sample_that_softens_early_loses_the_hot_entries():
    exp = template()
    # G_t' of (2.13) reaches zero 70 K above ambient instead of 153 K: the limit is 85 degC, past
    # which the 6 V steps held 6 s go (90 degC at the thesis values), while the program run so
    # far (78 degC) and the 2.5 V probe stay inside
    soft = exp.sample.replace(shear_modulus_slope=exp.sample.shear_modulus_slope * 153.0 / 70.0)
    assert sp.program_limit(soft, exp.rig, {}) is None
    why = sp.program_limit(soft, exp.rig, {"steps_s": 24.0})
    assert why is not None and "G_t'" in why and "85 degC" in why
    names = [n for n, _ in sp.design_menu(soft, exp.rig)]
    assert names[0] == "repeat (same protocol)" and not any(n.startswith("longer heating") for n in names)


def test_a_protocol_file_runs_on_the_virtual_rig(tmp_path):
    exp = template()
    table = dict(sp.design_menu(exp.sample, exp.rig))["load step on a held probe, 10 s hold"]
    path = tmp_path / "s.next.toml"
    path.write_text(protocol_toml(exp.raw, table, "test"), encoding="utf-8")
    assert load_experiment(path, require_runs=False).raw["protocol"] == table
    out = simulate("selfsensing", path, seed=2, out_dir=tmp_path / "sim")
    assert len(out.run_paths) == 2
    for p in out.run_paths:
        d = pd.read_csv(p)
        assert len(d) == 6000 and d["time_s"].iloc[-1] == pytest.approx(59.99)
        step = np.flatnonzero(np.diff(d["load_N"].to_numpy()))
        assert step.size == 1 and d["time_s"].iloc[step[0] + 1] == pytest.approx(55.0)


@pytest.mark.slow
def test_design_ranks_the_menu_on_a_selfsensing_diagnosis():
    exp = template()
    menu = sorted(n for n, _ in sp.design_menu(exp.sample, exp.rig))
    # clear: the protocols ranked by what they add to the precision of the explanation's parameters
    res = design(exp, SELFSENSING_ATTRIBUTED, n_draws=8)
    assert res.status == "clear" and sorted(c.name for c in res.candidates) == menu
    assert all(c.feasible and np.isfinite(c.information_gain) for c in res.candidates)
    assert res.best is not None and res.best.information_gain > 0
    # the same fits with coating-tcr left standing beside it: two hypotheses to separate
    aliased = {**SELFSENSING_ATTRIBUTED, "aliased_with": ["coating-tcr"]}
    res = design(exp, aliased, n_draws=8)
    assert res.status == "ambiguous" and [h["name"] for h in res.hypotheses] == [
        "resistance-drift",
        "coating-tcr",
    ]
    assert sorted(c.name for c in res.candidates) == menu and all(c.feasible for c in res.candidates)
    assert all(np.isfinite(c.separation_refit) and c.separation_refit > 0 for c in res.candidates)
    per_hour = [c.per_hour for c in res.candidates]
    assert per_hour == sorted(per_hour, reverse=True) and res.best is not None


def test_a_diagnosis_file_with_sorted_keys_reads_in_the_fits_order():
    # diagnosis.json lists the recalibrated parameters alphabetically; their covariance is in
    # the fit's order (the kind's calibration order), so the design reads them in that order
    rec = SELFSENSING_ATTRIBUTED["ranking"][0]["recalibrated"]
    assert list(rec) == sorted(rec)
    (h,) = hypotheses(SELFSENSING_ATTRIBUTED, "selfsensing")
    # (a file written before the quadratic TCR was calibrated lacks it: read without it)
    assert [f[0] for f in h.fields] == [
        p.field for p in get_kind("selfsensing").calibration if p.field in rec
    ]
    assert "tcr2" not in rec and "tcr2" in [p.field for p in get_kind("selfsensing").calibration]
    shuffled = json.loads(json.dumps(SELFSENSING_ATTRIBUTED))
    for c in shuffled["ranking"]:
        c["recalibrated"] = dict(reversed(list(c["recalibrated"].items())))
    (g,) = hypotheses(shuffled, "selfsensing")
    assert g.fields == h.fields and np.array_equal(g.values, h.values) and np.array_equal(g.cov_u, h.cov_u)
    # R0 is the best pinned of them (0.12 % of its value), damping the least (0.14, near its prior)
    sd = dict(zip((f[0] for f in h.fields), np.sqrt(np.diag(h.cov_u))))
    assert min(sd, key=sd.get) == "initial_resistance" and sd["initial_resistance"] < 2e-3
    assert max(sd, key=sd.get) == "damping" and sd["damping"] > 0.1
