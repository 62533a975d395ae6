"""The closed loop's bookkeeping: the default comparison and the before/after scores."""

from __future__ import annotations

import pytest

from tcamlab.benchmark import closed_loop_scores, loop_tasks, promise_scores
from tcamlab.design import DECISIVE
from tcamlab.design.protocols import kind_module
from tcamlab.loop import DEFAULT_PROTOCOL, at_least_default, realised_sd, within_reach


def _p(j, runs, feasible=True, decisive=None):
    decisive = j >= DECISIVE if decisive is None else decisive
    return {"protocol": "p", "separation": j, "runs": runs, "feasible": feasible, "decisive": decisive}


def test_designed_against_the_default():
    assert at_least_default(_p(5.0, 2), _p(4.0, 2)) is True
    assert at_least_default(_p(3.0, 2), _p(4.0, 2)) is False
    # the chosen one expected to decide: the cheaper is not worse
    assert at_least_default(_p(DECISIVE + 1, 2), _p(10 * DECISIVE, 4)) is True
    assert at_least_default(_p(DECISIVE - 1, 2), _p(10 * DECISIVE, 4)) is False
    # a large J that would not decide at the fitted effect sizes does not beat a decisive choice
    assert at_least_default(_p(DECISIVE + 1, 2), _p(10 * DECISIVE, 2, decisive=False)) is True
    assert at_least_default(_p(DECISIVE + 1, 2, decisive=False), _p(10 * DECISIVE, 2)) is False
    # more runs than the default is worse even with more separation
    assert at_least_default(_p(50.0, 6), _p(4.0, 4)) is False
    # a default outside the sample's limits cannot be run: the design wins
    assert at_least_default(_p(1.0, 2), _p(float("nan"), 4, feasible=False)) is True
    assert at_least_default(None, _p(1.0, 2)) is None and at_least_default(_p(1.0, 2), None) is None
    assert at_least_default(_p(float("nan"), 2), _p(1.0, 2)) is None


def _case(verdict, effect, after_verdict, after_effect, flag):
    digest = {"aliased_with": [], "ranking": [], "recalibrated": [], "recalibrated_aliases": []}
    return {
        "case": "single",
        "kind": "static",
        "effects": {"displacement-drift": 3.0},
        "seed": 1,
        "verdict": verdict,
        "effect": effect,
        **digest,
        "loop": {"chosen": _p(30.0, 4), "default": _p(8.0, 4), "at_least_default": flag},
        "after": {"verdict": after_verdict, "effect": after_effect, **digest},
    }


def test_closed_loop_scores_count_before_and_after():
    rows = [
        _case("miscalibrated", None, "attributed", "displacement-drift", True),
        _case("miscalibrated", None, "miscalibrated", None, False),
        {**_case("attributed", "displacement-drift", "x", None, None), "after": None},
    ]
    sc = closed_loop_scores(rows)
    before, after = sc["before"]["effect-only"]["3.0"], sc["after"]["effect-only"]["3.0"]
    assert before["n"] == after["n"] == 3
    assert before["top1"] == 1 / 3  # only the third, attributed from the start
    assert after["top1"] == 2 / 3  # the first now, the third keeps its first verdict
    assert sc["at_least_default"] == {"k": 1, "n": 2, "rate": 0.5}
    assert [c["after"] for c in sc["cases"]] == ["displacement-drift", "miscalibrated", "displacement-drift"]


def test_within_reach_compares_the_true_size_with_the_smallest_detectable():
    summary = {"smallest_detectable": {"g": {"slope": 3.5e4}, "two": {"a": 1.0, "b": 2.0}}}
    assert within_reach("g", {"slope": 2.9e3}, summary) is False
    assert within_reach("g", {"slope": -4e4}, summary) is True
    # two parameters: (0.8 / 1)^2 + (1.4 / 2)^2 = 1.13 >= 1, though each alone falls short
    assert within_reach("two", {"a": 0.8, "b": 1.4}, summary) is True
    assert within_reach("two", {"a": 0.5, "b": 1.0}, summary) is False
    assert within_reach("drift", {"drift": 1.0}, summary) is None  # not weighed by the design


def test_closed_loop_scores_leave_out_what_no_protocol_reaches():
    reach = {"smallest_detectable": {"displacement-drift": {"drift": 1e-9}}}
    far = {"smallest_detectable": {"displacement-drift": {"drift": 1e-6}}}
    rows = []
    for summary, after in ((reach, "displacement-drift"), (far, None), (reach, None)):
        c = _case("miscalibrated", None, "attributed" if after else "miscalibrated", after, True)
        c["loop"].update(summary)
        c["truth_values"] = {"displacement-drift": {"drift": 4e-9}}
        rows.append(c)
    w = closed_loop_scores(rows)["within_reach"]["effect-only"]["3.0"]
    assert w == {"k": 1, "n": 2, "rate": 0.5, "out_of_reach": 1}
    assert [c["reach"] for c in closed_loop_scores(rows)["cases"]] == [True, False, True]


def test_loop_tasks_keep_kinds_with_a_menu_and_one_case_per_family_when_quick():
    tasks = [
        {"case": "single", "kind": "static", "effects": {"a": 3.0}, "seed": 1},
        {"case": "single", "kind": "static", "effects": {"b": 3.0}, "seed": 1},
        {"case": "null", "kind": "static", "effects": {}, "seed": 2},
        {"case": "null", "kind": "selfsensing", "effects": {}, "seed": 2},
    ]
    quick = loop_tasks(tasks, quick=True)
    menu = hasattr(kind_module("selfsensing"), "design_menu")
    expected = [("single", {"a": 3.0}), ("null", {})] + [("null", {})] * menu
    assert [(t["case"], t["effects"]) for t in quick] == expected
    assert all(t["closed_loop"] for t in quick)
    assert len(loop_tasks(tasks, quick=False)) == 3 + menu
    assert set(DEFAULT_PROTOCOL) >= {"static", "dynamic", "sensing", "curvature"}


def test_simulate_runs_a_sensing_protocol_file_on_the_same_muscle(tmp_path):
    # Synthetic (virtual rig, seeds 3 and 9). The simulated sensing experiment keeps its rig's S
    # and R0 hidden, so a protocol file made from it lacks them; --truth supplies them from the
    # truth file, as the closed loop does, instead of refusing the file.
    from typer.testing import CliRunner

    from tcamlab.cli import app
    from tcamlab.config import load_experiment
    from tcamlab.design import protocol_toml
    from tcamlab.kinds.sensing import design_menu
    from tcamlab.rig import simulate
    from tcamlab.templates import TEMPLATES

    effects = {"stiffening-spring": 3.0}
    first = simulate(
        "sensing", TEMPLATES / "sensing.toml", seed=3, out_dir=tmp_path, effects=effects, name="sn"
    )
    exp = load_experiment(first.experiment_path)
    assert exp.rig.spring_constant is None  # hidden from the file
    template = load_experiment(TEMPLATES / "sensing.toml", require_runs=False)
    table = dict(design_menu(template.sample, template.rig)[0][1])
    nxt = tmp_path / "experiments" / "sn.next.toml"
    nxt.write_text(protocol_toml(exp.raw, table, "repeat"), encoding="utf-8")
    args = ["simulate", "sensing", "--experiment", str(nxt), "--truth", str(first.truth_path)]
    res = CliRunner().invoke(app, args + ["--seed", "9", "--out", str(tmp_path), "--name", "sn2"])
    assert res.exit_code == 0, res.output
    both = load_experiment(tmp_path / "experiments" / "sn2.toml")
    assert len(both.runs) == 3 + table["runs"]


@pytest.mark.slow
def test_a_second_hanging_load_tells_a_softening_coil_from_a_recalibration(tmp_path):
    # Synthetic (virtual rig, seed 1000): the voltage-step template's three runs at one load
    # and one voltage, the shear modulus softening the coil at 10x the noise. On one load a
    # recalibrated G_t slope fits as well (miscalibrated, the effect a stand-in); the coil's
    # compliance scales with the load and the torque does not, so the design hangs a second
    # load, and with those runs added the effect is named.
    import json

    from tcamlab.config import load_experiment
    from tcamlab.diagnosis import diagnose
    from tcamlab.loop import close_loop
    from tcamlab.rig import simulate
    from tcamlab.templates import TEMPLATES

    sim = simulate(
        "dynamic", TEMPLATES / "dynamic.toml", seed=1000, out_dir=tmp_path,
        effects={"shear-modulus-temperature": 10.0}, name="gt",
    )  # fmt: skip
    exp = load_experiment(sim.experiment_path)
    first = diagnose(exp, seed=0, workers=1).to_dict()
    assert first["verdict"] == "miscalibrated"
    assert "shear-modulus-temperature" in first["recalibration"]["stand_ins"]
    truth = json.loads(sim.truth_path.read_text())
    summary, second = close_loop(exp, first, truth, tmp_path, seed=1000)
    assert summary["chosen"]["protocol"] == "second load 2x" and summary["chosen"]["decisive"]
    assert summary["chosen"]["runs"] == 4
    logged = load_experiment(tmp_path / "experiments" / "gt-next.toml")  # every run so far
    runs = logged.read_runs()
    loads = sorted({round(float(r.data["load"].mean()), 6) for r in runs if "load" in r.data})
    assert loads == pytest.approx([0.05 * 9.80665, 0.1 * 9.80665], abs=1e-6)  # N, 50 g and 100 g
    assert (second["verdict"], second["effect"]) == ("attributed", "shear-modulus-temperature")


def test_the_design_promise_is_scored_against_the_second_diagnosis():
    promised = {"g": {"slope": 2.0e3}, "d": {"delay": 1e-3}}
    second = {
        "ranking": [
            {"effect": "g", "parameters": {"slope": {"value": 5e3, "stderr": 2.4e3, "at_bound": False}}},
            # at a bound: no Laplace interval, not compared
            {"effect": "d", "parameters": {"delay": {"value": 0.0, "stderr": 1e-4, "at_bound": True}}},
        ]
    }
    got = realised_sd(second, promised)
    assert got == {"g": {"slope": 2.4e3}}
    rows = [{"loop": {"promised_sd": promised, "realised_sd": got}}] + [
        {"loop": {"promised_sd": {"g": {"slope": 1.0}}, "realised_sd": {"g": {"slope": x}}}}
        for x in (0.5, 1.0)
    ]
    sc = promise_scores(rows)
    assert sc["n"] == 3 and sc["median"] == pytest.approx(1.0)
    assert sc["p10"] == pytest.approx(0.6) and sc["p90"] == pytest.approx(1.16)
    assert promise_scores([{"loop": {}}]) == {"n": 0, "median": None, "p10": None, "p90": None}
