"""Held-out and training rows of the diagnosis never share a row.

Design (tcamlab.diagnosis.folds / complement, read from the code):

* two or more runs: leave one run out -- fold i holds out every row of run i
  and nothing else;
* one run: contiguous blocks of that run, ``k`` of them (5 for >= 100 rows,
  else 3; never more than n // 3; at least 3 once n >= 9), edges
  ``linspace(0, n, k + 1)`` rounded;
* training rows = every row not held out, with no guard band; a run left
  with no training rows is dropped from the list.

So over all folds the held-out rows cover every row exactly once, and within
a fold training and held-out rows are disjoint and together are all rows.
"""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from tcamlab import diagnosis
from tcamlab.diagnosis import complement, folds


def _problem(lengths):
    """The fold builder reads only ``frames``."""
    return SimpleNamespace(frames=[pd.DataFrame({"x": np.arange(n, dtype=float)}) for n in lengths])


def _as_sets(rows):
    """(run, mask) pairs -> set of (run, row index); each run at most once."""
    runs = [i for i, _ in rows]
    assert len(runs) == len(set(runs)), f"a run appears twice: {runs}"
    return {(i, int(j)) for i, m in rows for j in np.flatnonzero(m)}


def _check(lengths):
    problem = _problem(lengths)
    everything = {(i, j) for i, n in enumerate(lengths) for j in range(n)}
    fs = folds(problem)
    assert fs, "no folds"
    seen: dict[tuple[int, int], int] = {}
    for held in fs:
        for i, m in held:
            assert m.dtype == bool and m.shape == (lengths[i],)
        held_set = _as_sets(held)
        assert held_set, "a fold holds out nothing"
        train = complement(problem, held)
        for i, m in train:
            assert m.dtype == bool and m.shape == (lengths[i],)
            assert m.any(), "a training entry with no rows"
        train_set = _as_sets(train)
        assert not (train_set & held_set), f"{len(train_set & held_set)} held-out rows in training"
        # no guard band: training is exactly all rows minus the held-out rows
        assert train_set == everything - held_set
        for key in held_set:
            seen[key] = seen.get(key, 0) + 1
    assert set(seen) == everything, "some rows are never held out"
    assert set(seen.values()) == {1}, "some rows are held out by more than one fold"
    return fs


@pytest.mark.parametrize(
    "lengths",
    [
        (7, 120),
        (50, 3, 200),
        (101, 101, 1, 64, 333),
        (2, 2),
    ],
)
def test_leave_one_run_out(lengths):
    fs = _check(lengths)
    # one fold per run, holding out that whole run and nothing else
    assert len(fs) == len(lengths)
    for i, held in enumerate(fs):
        assert [r for r, _ in held] == [i]
        assert held[0][1].all()
        # the held-out run is absent from training; every other run is there whole
        train = complement(_problem(lengths), held)
        assert [r for r, _ in train] == [r for r in range(len(lengths)) if r != i]
        assert all(m.all() for _, m in train)


@pytest.mark.parametrize(
    "n, k",
    [
        (6, 2),  # n // 3 = 2 blocks
        (9, 3),
        (10, 3),
        (57, 3),
        (99, 3),
        (100, 5),
        (101, 5),
        (1234, 5),
    ],
)
def test_single_run_blocks(n, k):
    fs = _check((n,))
    assert len(fs) == k
    starts = []
    for held in fs:
        ((run, m),) = held
        assert run == 0
        idx = np.flatnonzero(m)
        # contiguous block, sizes within one row of each other
        assert np.array_equal(idx, np.arange(idx[0], idx[-1] + 1))
        assert abs(idx.size - n / k) <= 1
        starts.append(idx[0])
        # training keeps the single run, minus the block
        ((trun, tm),) = complement(_problem((n,)), held)
        assert trun == 0 and int(tm.sum()) == n - idx.size
    assert starts == sorted(starts) and starts[0] == 0


@pytest.mark.parametrize("n", [1, 2, 5])
def test_single_short_run_has_one_fold_and_no_training_rows(n):
    # Below 6 rows there is room for only one block: it holds out everything and
    # the training set is empty (documented behaviour of the builder, not a leak).
    fs = folds(_problem((n,)))
    assert len(fs) == 1
    ((run, m),) = fs[0]
    assert run == 0 and m.all()
    assert complement(_problem((n,)), fs[0]) == []


@pytest.mark.parametrize("n_runs", [1, 2])
def test_diagnose_trains_on_the_complement(tmp_path, monkeypatch, n_runs):
    """End to end: what diagnose hands the candidate fits never includes held-out rows."""
    rig = pytest.importorskip("tcamlab.rig")
    from tcamlab.config import load_experiment

    templates = Path(__file__).resolve().parent.parent / "tcamlab" / "templates"
    sim = rig.simulate("static", templates / "static.toml", seed=3, out_dir=tmp_path, n_runs=n_runs)
    exp = load_experiment(sim.experiment_path)
    lengths = [len(r.data) for r in exp.read_runs()]
    everything = {(i, j) for i, n in enumerate(lengths) for j in range(n)}

    jobs = []
    from tcamlab.diagnosis import candidates

    real_job = candidates.candidate_job

    def spy(job):
        jobs.append(job)
        return real_job(job)

    monkeypatch.setattr(candidates, "candidate_job", spy)
    diagnosis.diagnose(exp, effects=["displacement-drift"], n_boot=10, workers=1)
    # recalibration alone, then the effect fitted with it
    assert [j[2] and j[2].name for j in jobs] == [None, "displacement-drift"]
    _problem_, _rec, _eff, held_sets, train_rows, *_ = jobs[1]
    assert len(held_sets) == len(train_rows) == (n_runs if n_runs > 1 else 3 if lengths[0] < 100 else 5)
    covered = []
    for held, train in zip(held_sets, train_rows):
        held_set, train_set = _as_sets(held), _as_sets(train)
        assert not (held_set & train_set)
        assert train_set == everything - held_set
        covered.extend(held_set)
    assert sorted(covered) == sorted(everything)
