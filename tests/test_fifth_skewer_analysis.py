"""Q4's analysis (``experiments/hierarchy/fifth_skewer.py``): the endpoint "skewer 5 fitted into
the watched organisation", Fisher's exact test and the five contrasts, checked on hand-made
records."""

import json
import sys
from pathlib import Path

import numpy as np
import pytest

HERE = Path(__file__).resolve().parents[1] / "experiments" / "hierarchy"


@pytest.fixture(scope="module")
def q4():
    sys.path.insert(0, str(HERE))
    try:
        import fifth_skewer

        yield fifth_skewer
    finally:
        sys.path.remove(str(HERE))


def _run(seed, watched, opens=True, focus=None, organisation="mixed", gap=0.1, first=100,
         windows=(1, 2, 3, 4)):  # fmt: skip
    return {
        "seed": seed,
        "watched": watched,
        "opens": opens,
        "focus_scores": focus or {"skewer": 0.0, "step": 0.0},
        "organisation": organisation,
        "value_gap": gap,
        "first_opening": first,
        "window_openings": list(windows),
        "options": 17,
    }


def test_skewer_5_fitted_by_the_focus_score_of_the_watched_organisation(q4):
    """Hand-solved with the box's scores: a skewer mentor's plan doing skewer 5 in one run has
    focus score 1 for "skewer"; a step mentor's plan needs score 1 for "step"; a plan that does
    not open never follows."""
    from himit_torch.worlds.puzzle_box import organisation_scores

    # 3 skewers of 2 steps, skewer 3 (index 2) last and in one run: fitted skewer by skewer
    block = [(0, 1), (0, 2), (1, 1), (1, 2), (2, 1), (2, 2)]
    # step by step across all three: skewer 3's step 1 after the others' step 1s, before 2s
    steps = [(0, 1), (1, 1), (2, 1), (0, 2), (1, 2), (2, 2)]
    focus_block = organisation_scores(block, 3, 2, focus=2)
    focus_steps = organisation_scores(steps, 3, 2, focus=2)
    assert focus_block == {"skewer": 1.0, "step": 0.5}
    assert focus_steps == {"skewer": 0.0, "step": 1.0}
    assert q4.follows_on_skewer_5(_run(0, "skewer", focus=focus_block))
    assert not q4.follows_on_skewer_5(_run(1, "step", focus=focus_block))
    assert q4.follows_on_skewer_5(_run(1, "step", focus=focus_steps))
    assert not q4.follows_on_skewer_5(_run(0, "skewer", opens=False, focus=focus_block))
    assert not q4.follows_on_skewer_5(_run(0, "skewer", focus={"skewer": None, "step": None}))


def test_fishers_exact_test_by_hand(q4):
    """3 of 3 against 0 of 3: the table and its mirror are the only ones as extreme, each of
    probability C(3,3)·C(3,0)/C(6,3) = 1/20, so the two-sided p is 0.1."""
    t = q4.fisher_test("x", "paper", [True] * 3, [False] * 3)
    assert t.p == pytest.approx(0.1)
    assert (t.wins, t.losses, t.difference) == (3, 0, 100.0)


def test_quarter_openings_count_the_windows_within_the_first_quarter(q4):
    """A 20,000-step run with windows of 2,000: the first quarter is 5,000 steps, 2 whole
    windows."""
    assert q4.goals_in_quarter(_run(0, "skewer", windows=range(1, 11)), 20_000, 2_000) == 3


def _cells(q4, gaps, firsts, follows):
    """Four cells of three seeds: per cell the seeds' value gaps, first openings and whether
    each follows (skewer mentors on seeds 0 and 2, step on 1)."""
    out = {}
    for cell in q4.CELLS:
        runs = []
        for seed in range(3):
            watched = ("skewer", "step")[seed % 2]
            focus = {watched: 1.0 if follows[cell][seed] else 0.5}
            runs.append(_run(seed, watched, focus=focus, gap=gaps[cell][seed],
                             first=firsts[cell][seed]))  # fmt: skip
        out[cell] = {"steps": 8, "window": 1, "runs": runs}
    return out


def test_the_five_contrasts_and_the_routines_effect_on_imitation(q4):
    """Hand-solved on the value gap: routines' effect on imitation per seed (0.1 − 0.3) − (0.2
    − 0.2) = −0.2, (0.1 − 0.5) − (0.3 − 0.4) = −0.3, (0.2 − 0.3) − (0.2 − 0.2) = −0.1: mean
    −0.2, lower gaps, so the routines help imitation there; eq. 2 routines − given: −0.1,
    −0.2, 0.0: mean −0.1. On the first opening, the speed-ups (control − imitator, never at
    the budget of 8 steps) are 3, 8 − 2 = 6, 1 with routines and 0, 1, −1 with the given
    options: all three differences positive."""
    gaps = {"relative_eq2": [0.1, 0.1, 0.2], "relative_options": [0.3, 0.5, 0.3],
            "given_eq2": [0.2, 0.3, 0.2], "given_options": [0.2, 0.4, 0.2]}  # fmt: skip
    firsts = {"relative_eq2": [2, 2, 4], "relative_options": [5, -1, 5],
              "given_eq2": [5, 4, 6], "given_options": [5, 5, 5]}  # fmt: skip
    follows = {"relative_eq2": [True, True, False], "relative_options": [True, False, False],
               "given_eq2": [False] * 3, "given_options": [False] * 3}  # fmt: skip
    tests = {(t.name, t.endpoint): t for t in q4.q4_tests("paper", _cells(q4, gaps, firsts,
                                                                          follows))}  # fmt: skip
    assert len(tests) == 18
    effect = tests[q4.EFFECT, "value_gap"]
    assert effect.difference == pytest.approx(-0.2)
    assert (effect.wins, effect.losses) == (0, 3)
    direct = tests["eq. 2 with routines − eq. 2 with the given options", "value_gap"]
    assert direct.difference == pytest.approx(np.mean([-0.1, -0.2, 0.0]))
    speed = tests[q4.EFFECT, "first_opening"]
    assert (speed.wins, speed.losses) == (3, 0)
    assert speed.difference == pytest.approx(np.mean([3, 5, 2]))
    fisher = tests["eq. 2: routines against the given options", "follows"]
    assert (fisher.wins, fisher.losses) == (2, 0)
    # 2 of 3 against 0 of 3: P(k of the 2 followers in row a) = C(3,k)·C(3,2−k)/C(6,2), 3/15 at
    # k = 2 and at k = 0 (9/15 at k = 1): p = 0.4
    assert fisher.p == pytest.approx(0.4)


def test_loading_needs_all_four_cells_of_a_schedule(q4, tmp_path):
    record = {"steps": 8, "window": 1, "runs": [_run(0, "skewer")]}
    for cell in list(q4.CELLS)[:3]:
        (tmp_path / f"q4_paper_{cell}.json").write_text(json.dumps(record))
    cells, missing = q4.load_q4(tmp_path)
    assert cells == {}
    assert "q4_paper_given_options" in missing
    (tmp_path / "q4_paper_given_options.json").write_text(json.dumps(record))
    cells, _ = q4.load_q4(tmp_path)
    assert list(cells) == ["paper"]


@pytest.mark.slow
def test_a_short_run_reproduces_the_committed_q4_records(q4, tmp_path):
    """The first windows of seeds 0 and 1 (a skewer-by-skewer and a step-by-step mentor) of the
    committed eq. 2 with skewer routines, paper's ε, rerun with the code as it is now: the same
    routines and the same openings per window (learning is causal, so a shorter budget gives
    the same first windows)."""
    import q4_fifth_skewer as runner

    record = json.loads((HERE.parent / "results" / "hierarchy" / "q4_paper_relative_eq2.json")
                        .read_text())  # fmt: skip
    windows = 3
    out = runner.run_setting(seeds=2, first_seed=0, steps=windows * record["window"])
    again = runner.run_cell(*out, "paper", "relative_eq2")
    for mine, theirs in zip(again["runs"], record["runs"][:2]):
        assert mine["routines"] == theirs["routines"]
        assert mine["window_openings"] == theirs["window_openings"][:windows]
