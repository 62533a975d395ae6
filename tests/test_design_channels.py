"""The design scores the channels a protocol adds: a voltage-step run that logs the current
tells a resistance that rises with temperature from a convective heat loss, which the
displacement alone confuses; a protocol without a channel scores as it did; the noise of an
added channel is the diagnosis's floor when it scored the quantity, else the chain's sd; the
protocol file carries the channels and the virtual rig logs them."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import tcamlab.design
from tcamlab.config import load_experiment
from tcamlab.design import design, protocol_toml
from tcamlab.design.protocols import channel_noise, protocol_frames, protocol_quantities
from tcamlab.design.toml import KEY_DOCS
from tcamlab.kinds import dynamic, get_kind, static
from tcamlab.rig import simulate
from tcamlab.templates import TEMPLATES

# A voltage-step diagnosis as tcamlab diagnose wrote it (synthetic, seed 1000: three runs at
# one voltage, no current logged, a resistance rising with temperature at 3x withheld):
# aliased, convective-heat-loss and resistance-temperature fit the withheld runs alike. Made
# by tests/data/design/make_dynamic_aliased.py; only the fields design reads.
DYNAMIC_ALIASED = json.loads(
    (Path(__file__).parent / "data" / "design" / "dynamic_aliased.diagnosis.json").read_text()
)

N_DRAWS = 12


def template():
    return load_experiment(TEMPLATES / "dynamic.toml", require_runs=False)


def by_name(res) -> dict:
    return {c.name: c for c in res.candidates}


def without(table: dict, key: str) -> dict:
    return {k: v for k, v in table.items() if k != key}


@pytest.fixture(scope="module")
def aliased():
    return design(template(), DYNAMIC_ALIASED, n_draws=N_DRAWS)


PAIR = "convective-heat-loss vs resistance-temperature"
RECAL_PAIR = "recalibration vs convective-heat-loss"


def test_logging_the_current_separates_rt_from_a_convective_loss(aliased):
    assert aliased.status == "ambiguous"
    # an aliased verdict keeps recalibration among the hypotheses: the new runs test it again
    assert {h["name"] for h in aliased.hypotheses} == {
        "recalibration",
        "resistance-temperature",
        "convective-heat-loss",
    }
    by = by_name(aliased)
    log, repeat = by["log the current"], by["repeat (same protocol)"]
    # the same protocol, the current added: the same runs and rig time
    assert log.table["channels"] == [*repeat.table["channels"], "current_A"]
    assert (log.runs, log.minutes) == (repeat.runs, repeat.minutes)
    # I = V / R(T): constant under a convective loss, falling as the coil heats under R(T)
    assert log.refit[PAIR] > 1e4 * repeat.refit[PAIR]
    assert log.refit[PAIR] > 1e4 * by["second voltage 0.8x"].refit[PAIR]
    assert log.max_difference[PAIR]["current"] > 0.01  # A
    # but a heat loss leaves the current as a recalibration of the thermal constants does:
    # that pair is the repeat's, so the current alone is not the best protocol
    assert log.refit[RECAL_PAIR] == pytest.approx(repeat.refit[RECAL_PAIR], rel=1e-6)
    assert log.separation_refit == pytest.approx(repeat.refit[RECAL_PAIR], rel=1e-6)
    best = aliased.best
    assert best is aliased.candidates[0] and best.decisive and best.name != "log the current"
    assert min(best.refit.values()) > log.separation_refit
    assert best.name in aliased.message and "is expected to decide" in aliased.message


def test_without_the_channel_the_protocol_scores_as_the_repeat(monkeypatch):
    # the channel-less path: every protocol scored on the kind's outputs only
    outputs = tuple(get_kind("dynamic").outputs)
    monkeypatch.setattr(tcamlab.design, "protocol_quantities", lambda kind, table: outputs)
    res = design(template(), DYNAMIC_ALIASED, n_draws=N_DRAWS)
    by = by_name(res)
    log, repeat = by["log the current"], by["repeat (same protocol)"]
    assert log.separation_refit == repeat.separation_refit and log.separation == repeat.separation
    assert log.at_fit == repeat.at_fit
    assert not dynamic.protocol_channels(res.best.table["channels"])


def test_a_protocol_without_channels_scores_exactly_as_before(aliased, monkeypatch):
    # the menu as it was, without the entries that log a channel: every protocol the two share
    # scores the same, and the best logs no channel
    full = dynamic.design_menu
    monkeypatch.setattr(
        dynamic,
        "design_menu",
        lambda s, r: [(n, t) for n, t in full(s, r) if not dynamic.protocol_channels(t["channels"])],
    )
    old = design(template(), DYNAMIC_ALIASED, n_draws=N_DRAWS)
    assert not dynamic.protocol_channels(old.best.table["channels"])
    new = by_name(aliased)
    assert set(by_name(old)) < set(new)
    for name, c in by_name(old).items():
        n = new[name]
        assert protocol_quantities("dynamic", c.table) == ("displacement",)
        assert c.feasible == n.feasible and c.limit == n.limit
        if c.feasible:
            assert (c.separation_refit, c.separation, c.beyond_repeat) == (
                n.separation_refit,
                n.separation,
                n.beyond_repeat,
            )
            assert c.at_fit == n.at_fit and c.max_difference == n.max_difference


def test_a_kind_without_channels_scores_its_outputs():
    exp = load_experiment(TEMPLATES / "static.toml", require_runs=False)
    for _, table in static.design_menu(exp.sample, exp.rig):
        assert protocol_quantities("static", table) == tuple(get_kind("static").outputs)
    assert channel_noise("static", (), {"displacement": 1e-6}) == {"displacement": 1e-6}


def test_the_current_noise_is_the_diagnosis_floor_else_the_chain_sd(aliased):
    sd = dynamic.channel_sd()
    # the first runs logged no current: the current sense's sd
    assert aliased.noise["current"] == sd["current"] and aliased.noise["temperature"] == sd["temperature"]
    assert channel_noise("dynamic", ("current",), {"displacement": 6e-6}) == {
        "displacement": 6e-6,
        "current": sd["current"],
    }
    # a diagnosis that scored a logged current: its floor (display units, A), here 10x the chain's
    floor = 10.0 * sd["current"]
    scored = json.loads(json.dumps(DYNAMIC_ALIASED))
    scored["noise_floor"]["by_quantity"]["current"] = {"sigma": floor, "unit": "A"}
    res = design(template(), scored, n_draws=N_DRAWS)
    assert res.noise["current"] == pytest.approx(floor, rel=1e-12)
    assert res.noise["temperature"] == sd["temperature"]
    a, b = by_name(aliased)["log the current"], by_name(res)["log the current"]
    # J is mostly the mean term, r^2 / s^2: a noise 10x larger divides it by about 100
    assert 30 < a.refit[PAIR] / b.refit[PAIR] < 300
    # a protocol without the current is unmoved
    rep = "second voltage 0.8x"
    assert by_name(res)[rep].separation_refit == by_name(aliased)[rep].separation_refit


def test_every_dynamic_menu_entry_runs_and_documents_its_keys():
    exp = template()
    menu = dynamic.design_menu(exp.sample, exp.rig)
    names = [n for n, _ in menu]
    assert names[:6] == [
        "repeat (same protocol)",
        "second voltage 0.8x",
        "second voltage 1.2x",
        "shorter pulse 0.5x",
        "longer pulse 2x",
        "pulse train of 3",
    ]
    assert len(set(names)) == len(names)
    base = dict(menu)["repeat (same protocol)"]
    assert base["channels"] == ["time_s", "voltage_V", "displacement_mm"]
    logged = {n: dynamic.protocol_channels(t["channels"]) for n, t in menu}
    assert logged["log the current"] == ("current",) and logged["log the temperature"] == ("temperature",)
    assert logged["log the current, second voltage 0.8x"] == ("current",)
    assert all(not logged[n] for n in names[:6])
    for name, table in menu:
        assert set(table) <= set(dynamic.PROTOCOL_KEYS) and set(table) <= set(KEY_DOCS)
        assert len(protocol_frames("dynamic", exp.rig, table)) == table["runs"], name


def test_the_protocol_file_logs_the_current_on_the_virtual_rig(tmp_path):
    exp = template()
    table = dict(dynamic.design_menu(exp.sample, exp.rig))["log the current"]
    path = tmp_path / "d.next.toml"
    path.write_text(protocol_toml(exp.raw, table, "test"), encoding="utf-8")
    assert load_experiment(path, require_runs=False).raw["protocol"] == table
    out = simulate("dynamic", path, seed=2, out_dir=tmp_path / "sim")
    assert len(out.run_paths) == 2
    for p in out.run_paths:
        log = pd.read_csv(p)
        assert list(log.columns) == ["time_s", "voltage_V", "displacement_mm", "current_A"]
        on = log["voltage_V"] > 0
        # 10 V on 40 ohm with the template's R(T) constant: 0.25 A on the pulse, none off it
        # (within the sense's noise and ADC step)
        assert on.sum() == 100 and np.max(np.abs(log.loc[on, "current_A"] - 0.25)) < 1e-3
        assert np.max(np.abs(log.loc[~on, "current_A"])) <= 2e-4


@pytest.mark.slow
def test_the_loop_logs_the_channel_the_design_asks_for(tmp_path):
    # Synthetic (virtual rig, seeds 1000 and 1001): the case of DYNAMIC_ALIASED made afresh,
    # diagnosed, designed, and the designed protocol run on the same muscle. With recalibration
    # weighed beside the two aliases, the thermocouple separates every pair: the temperature.
    from tcamlab.diagnosis import diagnose
    from tcamlab.pipeline import simulate_experiment

    first = simulate(
        "dynamic",
        TEMPLATES / "dynamic.toml",
        seed=1000,
        out_dir=tmp_path,
        effects={"resistance-temperature": 3.0},
        name="rt",
    )
    exp = load_experiment(first.experiment_path)
    d1 = diagnose(exp, seed=0).to_dict()
    assert d1["verdict"] == "aliased"
    assert {d1["effect"], *d1["aliased_with"]} == {"resistance-temperature", "convective-heat-loss"}
    res = design(exp, d1)
    assert res.best.name == "log the temperature" and res.best.decisive
    nxt = tmp_path / "experiments" / "rt.next.toml"
    nxt.write_text(protocol_toml(exp.raw, res.best.table, "t"), encoding="utf-8")
    second = simulate_experiment(
        "dynamic", str(nxt), seed=1001, out_dir=tmp_path, name="rt2", truth=first.truth_path
    )
    both = load_experiment(second.experiment_path)
    assert len(both.runs) == 3 + res.best.runs
    new = [pd.read_csv(tmp_path / "experiments" / p) for p in both.raw["runs"][3:]]
    assert all("temperature_C" in log.columns and "current_A" not in log.columns for log in new)


def test_an_aliased_verdict_weighs_recalibration_where_its_fit_is_given():
    from tcamlab.design.hypotheses import hypotheses

    names = [h.name for h in hypotheses(DYNAMIC_ALIASED, "dynamic")]
    assert names == ["recalibration", "convective-heat-loss", "resistance-temperature"]
    # a diagnosis file cut by hand to the aliases' fits: the aliases alone, not an error
    cut = {
        **DYNAMIC_ALIASED,
        "ranking": [c for c in DYNAMIC_ALIASED["ranking"] if c["effect"] != "recalibration"],
    }
    assert [h.name for h in hypotheses(cut, "dynamic")] == ["convective-heat-loss", "resistance-temperature"]


def test_a_fit_hotter_than_the_limit_on_the_runs_made_forbids_only_hotter_protocols(monkeypatch):
    # The sample survived the runs already made, so a fit that puts them above the temperature
    # limit can rule out only what heats further. (Synthetic, stated G_t' = 0 and a convective
    # loss at 3x: the R(T) fit put the pulse at 182 degC against 170, and every protocol, the
    # repeat of what was run included, came out of bounds.) Here every fit of DYNAMIC_ALIASED
    # peaks near 100 degC, above a limit lowered to 40.
    monkeypatch.setattr(tcamlab.design.predict, "TEMPERATURE_LIMIT_C", 40.0)
    res = design(template(), DYNAMIC_ALIASED, n_draws=N_DRAWS)
    c = by_name(res)
    assert c["repeat (same protocol)"].feasible and c["shorter pulse 0.5x"].feasible
    assert c["log the current"].feasible
    assert not c["pulse train of 3"].feasible
    assert "it predicts for the runs already made" in c["pulse train of 3"].limit
    assert res.best is not None and res.best.name == "log the temperature"


def test_the_limit_alone_holds_where_the_runs_made_stay_below_it():
    from tcamlab.design.predict import TEMPERATURE_LIMIT_C, limits

    frames = [{"temperature": np.array([20.0, 60.0])}]
    hot = [{"temperature": np.array([20.0, TEMPERATURE_LIMIT_C + 5.0]), "displacement": np.zeros(2)}]
    assert "limit" in limits("dynamic", None, frames, hot)
    assert "limit" in limits("dynamic", None, frames, hot, ceiling=TEMPERATURE_LIMIT_C - 30.0)
    assert limits("dynamic", None, frames, hot, ceiling=TEMPERATURE_LIMIT_C + 5.0) is None
    assert "runs already made" in limits("dynamic", None, frames, hot, ceiling=TEMPERATURE_LIMIT_C + 2.0)
