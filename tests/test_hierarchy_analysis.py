"""The hierarchy study's analysis (``experiments/hierarchy/``): each pair of runs counted once,
and hierarchy's effect on imitation as the difference of the two imitation effects, checked on
hand-made records."""

import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

HERE = Path(__file__).resolve().parents[1] / "experiments" / "hierarchy"


@pytest.fixture(scope="module")
def analysis():
    sys.path.insert(0, str(HERE))
    try:
        import common
        import where_pays

        yield common, where_pays
    finally:
        sys.path.remove(str(HERE))


def _test(common, name, world="exp1", schedule="paper", endpoint="greedy", difference=-1.0):
    return common.Test("F", name, world, "", schedule, "a", "b", endpoint, difference, -2.0, 0.0,
                       0.01, 3, 17)  # fmt: skip


def test_a_comparison_of_the_same_runs_is_counted_once(analysis):
    common, _ = analysis
    first = [_test(common, "trial"), _test(common, "trial", endpoint="goals", difference=5.0)]
    same = [_test(common, "trial + feasibility"),
            _test(common, "trial + feasibility", endpoint="goals", difference=5.0)]  # fmt: skip
    other_world = [_test(common, "trial", world="exp2"),
                   _test(common, "trial", world="exp2", endpoint="goals", difference=5.0)]  # fmt: skip
    other_numbers = [_test(common, "off"), _test(common, "off", endpoint="goals", difference=6.0)]
    kept, repeats = common.distinct_comparisons(first + same + other_world + other_numbers)
    assert repeats == [("trial + feasibility", "exp1", "", "paper")]
    assert kept == first + other_world + other_numbers


def test_hierarchys_effect_is_the_difference_of_the_imitation_effects(analysis):
    """Hand-solved: per seed (eq. 2 − options only) − (eq. 1 − primitives only) on the greedy
    policy is (50 − 10) − (20 − 20) = 40, (60 − 30) − (25 − 15) = 20, (70 − 20) − (30 − 10) = 30:
    mean 30; eq. 2 − eq. 1 is 30, 35, 40: mean 35."""
    _, wp = analysis
    values = {"imitation": [50, 60, 70], "options": [10, 30, 20],
              "imitation_primitives": [20, 25, 30], "primitives": [20, 15, 10]}  # fmt: skip
    arrays = {a: np.array(v, dtype=float) for a, v in values.items()}
    cell = wp.Cell("taxi", "paper", 1000, "abc", (0, 1, 2), arrays,
                   {a: np.array([10, -1, 30]) for a in values}, arrays, 250)  # fmt: skip
    tests = {(t.name, t.endpoint): t for t in wp.cell_tests("Q1", cell)}
    assert tests[wp.HIERARCHY, "greedy"].difference == pytest.approx(30.0)
    assert (tests[wp.HIERARCHY, "greedy"].wins, tests[wp.HIERARCHY, "greedy"].losses) == (3, 0)
    assert tests[wp.DIRECT, "greedy"].difference == pytest.approx(35.0)
    own = "options' own effect (options only − primitives only)"
    assert tests[own, "greedy"].difference == pytest.approx(np.mean([-10, 15, 10]))
    # the same first goals for every learner: no speed-up differs, every sign test is a tie
    assert tests[wp.HIERARCHY, "first_goal"].difference == 0.0
    assert tests[wp.HIERARCHY, "first_goal"].p == 1.0


def test_the_budget_rule_is_the_least_multiple_of_10k_by_which_half_have_reached_the_goal(
    analysis,
):
    """Hand-solved: of four runs, two must have reached the goal; the 2nd smallest first goal
    decides (12,001 → 20k; 10,000 → 10k; a run that never did counts as never)."""
    common, _ = analysis
    assert common.budget_by_rule([30_000, 12_001, 5, None]) == 20_000
    assert common.budget_by_rule([10_000, 3, -1, -1]) == 10_000
    assert common.budget_by_rule([49, 225]) == 10_000  # at least one step of 10k
    assert common.budget_by_rule([7, None, None]) is None  # 1 of 3 reached: fewer than half
    assert common.budget_by_rule([25_000, 41_000, None, None], step=20_000) == 60_000


def _cell(wp, greedy, first_goal, goals, seeds=(0, 1, 2)):
    return wp.Cell("taxi", "paper", 1000, "abc", seeds, {wp.EQ2: np.array(greedy, dtype=float)},
                   {wp.EQ2: np.array(first_goal)}, {wp.EQ2: np.array(goals, dtype=float)},
                   250)  # fmt: skip


def test_feasibility_is_compared_with_trial_alone_paired_by_seed(analysis):
    """Hand-solved: greedy 40, 50, 60 with feasibility against 30, 50, 70 with trial alone:
    differences +10, 0, −10 (mean 0, one seed won, one lost); first goals 5, 20, never against
    10, 20, 30: one sooner, one tie, one later (never loses)."""
    _, wp = analysis
    trial = _cell(wp, [30, 50, 70], [10, 20, 30], [1, 2, 3])
    feasible = _cell(wp, [40, 50, 60], [5, 20, -1], [2, 4, 6])
    tests = {t.endpoint: t for t in wp.f_tests(trial, feasible, 1)}
    assert tests["greedy"].name == "N = 1 − trial alone"
    assert tests["greedy"].difference == pytest.approx(0.0)
    assert (tests["greedy"].wins, tests["greedy"].losses) == (1, 1)
    assert (tests["first_goal"].wins, tests["first_goal"].losses) == (1, 1)
    assert tests["goals_q1"].difference == pytest.approx(2.0)
    with pytest.raises(ValueError, match="seeds differ"):
        wp.f_tests(trial, _cell(wp, [1, 2], [1, 2], [1, 2], seeds=(0, 1)), 3)


def test_a_run_is_changed_where_any_window_of_its_record_differs(analysis):
    _, wp = analysis
    base = {("imitation", 0): (("2000", "5"),), ("imitation", 1): (("2000", "7"),)}
    same_and_one_window_differs = {("imitation", 0): (("2000", "5"),),
                                   ("imitation", 1): (("2000", "8"),)}  # fmt: skip
    assert wp.runs_changed(base, base) == (0, 2)
    assert wp.runs_changed(base, same_and_one_window_differs) == (1, 2)
    with pytest.raises(ValueError, match="seeds"):
        wp.runs_changed(base, {("imitation", 0): (("2000", "5"),)})


def _write_sweep(directory, rows, strides=("",)):
    """A tiny sweep record: runs.csv, results.csv (two windows a run) and sweep.json."""
    import csv
    import json

    directory.mkdir(parents=True)
    fields = ["agent", "seed", "preset", "observation_stride", "greedy_percent_of_optimal",
              "first_goal_step"]  # fmt: skip
    with (directory / "runs.csv").open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(fields)
        for stride in strides:
            for agent, seed, preset, greedy, first in rows:
                w.writerow([agent, seed, preset, stride, greedy, first])
    with (directory / "results.csv").open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["agent", "seed", "preset", "observation_stride", "step", "goals_in_window"])
        for stride in strides:
            for agent, seed, preset, greedy, _ in rows:
                w.writerow([agent, seed, preset, stride, 50_000, int(greedy) // 10])
                w.writerow([agent, seed, preset, stride, 55_000, 100])  # after the quarter
    (directory / "sweep.json").write_text(json.dumps({"commit": "abcdef123"}))


def test_q2s_controls_serve_every_observation_and_early_goals_stop_at_the_quarter(
    analysis, tmp_path
):
    """Hand-made exp2 records (budget 200k: the quarter ends at 50k): the imitators' sweeps at
    the option ends and at strides 10 and 20, the controls once; each of the 3 observations × 2
    schedules is a cell with the same control runs; exp1's sweeps are absent and said so."""
    _, wp = analysis
    imitators = [(a, s, p, g, f) for p in ("paper", "explore-goals")
                 for a, g in (("imitation", 60), ("imitation_primitives", 40))
                 for s, f in ((0, 300), (1, -1))]  # fmt: skip
    controls = [(a, s, p, g, 500) for p in ("paper", "explore-goals")
                for a, g in (("options", 30), ("primitives", 20)) for s in (0, 1)]  # fmt: skip
    _write_sweep(tmp_path / "q2_ends_exp2", imitators)
    _write_sweep(tmp_path / "q2_stride_exp2", imitators, strides=("10", "20"))
    _write_sweep(tmp_path / "q2_controls_exp2", controls)
    cells, missing = wp.load_q2_cells(tmp_path)
    assert [m for m in missing if m.endswith("exp1")] == ["q2_controls_exp1", "q2_ends_exp1",
                                                   "q2_stride_exp1"]  # fmt: skip
    assert len(missing) == 3 + 3 * 3 * 2  # and every MiniGrid cell (task × observation × schedule)
    assert [(c.condition, c.schedule) for c in cells] == [
        (o, p)
        for o in ("option ends", "stride 10", "stride 20")
        for p in ("paper", "explore-goals")
    ]
    for cell in cells:
        assert cell.seeds == (0, 1) and cell.budget == 200_000
        assert cell.greedy["options"].tolist() == [30, 30]
        assert cell.first_goal["imitation"].tolist() == [300, -1]
        # only the window ending at 50k counts: greedy // 10
        assert cell.goals_q1["imitation"].tolist() == [6, 6]
        assert cell.goals_q1["primitives"].tolist() == [2, 2]
        tests = {(t.name, t.endpoint): t for t in wp.cell_tests("Q2", cell)}
        # (60 − 30) − (40 − 20) = 10 on every seed
        assert tests[wp.HIERARCHY, "greedy"].difference == pytest.approx(10.0)
        assert tests[wp.HIERARCHY, "greedy"].condition == cell.condition


def _q3_cell(wp, condition, greedy, first_goal, schedule="paper", seeds=(0, 1, 2)):
    """A Q3 cell of DoorKey 5×5's transfer task: greedy and first goals per learner; the early
    goals are the greedy values (so that their contrasts are the greedy ones)."""
    arrays = {a: np.array(v, dtype=float) for a, v in greedy.items()}
    return wp.Cell("doorkey5x5_transfer", schedule, 1000, "abc", seeds, arrays,
                   {a: np.array(v) for a, v in first_goal.items()}, arrays, 250,
                   condition)  # fmt: skip


def test_q3s_mechanism_is_the_imitation_effect_at_0_minus_at_minus_1(analysis):
    """Hand-solved. Greedy: at −1, eq. 2 − options only = 0, 0, 0 and eq. 1 − primitives only
    = 10, 0, −10; at 0, eq. 2 − options only = 30, 20, 40 (mean 30) and eq. 1's = 10, 0, −10.
    So eq. 2's effect 0 − −1 is 30, 20, 40 (mean 30, 3–0) and eq. 1's 0, 0, 0. First goals
    (budget 1000, never = −1): at −1 eq. 2 equals options only on every seed (speed-ups 0); at
    0 options only 500, never, 300 and eq. 2 100, 200, 300: speed-ups 400, 800 (never counted
    at 1000), 0; their difference with −1's is 400, 800, 0: mean 400, 2 won, 1 tie."""
    _, wp = analysis
    minus = _q3_cell(wp, wp.Q3_VALUES["-1"],
                     {"imitation": [50, 60, 70], "options": [50, 60, 70],
                      "imitation_primitives": [30, 20, 10], "primitives": [20, 20, 20]},
                     {"imitation": [100, -1, 300], "options": [100, -1, 300],
                      "imitation_primitives": [7, 8, 9], "primitives": [7, 8, 9]})  # fmt: skip
    zero = _q3_cell(wp, wp.Q3_VALUES["0"],
                    {"imitation": [80, 80, 110], "options": [50, 60, 70],
                     "imitation_primitives": [30, 20, 10], "primitives": [20, 20, 20]},
                    {"imitation": [100, 200, 300], "options": [500, -1, 300],
                     "imitation_primitives": [7, 8, 9], "primitives": [7, 8, 9]})  # fmt: skip
    tests = {(t.name.split("'s")[0], t.endpoint): t for t in wp.mechanism_tests([minus, zero])}
    assert len(tests) == 6 and {t.world for t in tests.values()} == {"doorkey5x5_transfer"}
    assert tests["eq. 2", "greedy"].difference == pytest.approx(30.0)
    assert (tests["eq. 2", "greedy"].wins, tests["eq. 2", "greedy"].losses) == (3, 0)
    assert tests["eq. 1", "greedy"].difference == pytest.approx(0.0)
    assert tests["eq. 1", "greedy"].p == 1.0 or np.isnan(tests["eq. 1", "greedy"].p)
    first = tests["eq. 2", "first_goal"]
    assert first.difference == pytest.approx(400.0) and (first.wins, first.losses) == (2, 0)
    assert first.p == pytest.approx(0.5)  # the sign test: 2 of 2 non-ties, two-sided
    # first goals equal to the control's: 3 of 3 at −1, 1 of 3 (seed 2) at 0
    assert wp.first_goals_equal(minus, wp.EQ2) == 3 and wp.first_goals_equal(zero, wp.EQ2) == 1
    with pytest.raises(ValueError, match="seeds differ"):
        wp.mechanism_tests([minus, _q3_cell(wp, wp.Q3_VALUES["0"], {"imitation": [1, 2]},
                                            {"imitation": [1, 2]}, seeds=(0, 1))])  # fmt: skip


def test_q3s_transfer_cost_pairs_each_imitator_with_its_q1_cell(analysis):
    """Hand-solved: eq. 2 watching the moved goal's mentor 50, 60, 70 against 80, 60, 40 in
    Q1's cell: −30, 0, +30 (mean 0, 1–1); eq. 1 40, 40, 40 against 10, 20, 30: mean +20 (3–0).
    Only the initial value −1's cells have a Q1 twin; the 0 cells are left out."""
    _, wp = analysis
    q3 = _q3_cell(wp, wp.Q3_VALUES["-1"],
                  {"imitation": [50, 60, 70], "imitation_primitives": [40, 40, 40]},
                  {"imitation": [1, 2, 3], "imitation_primitives": [1, 2, 3]})  # fmt: skip
    q1 = wp.Cell("doorkey5x5", "paper", 1000, "abc", (0, 1, 2),
                 {"imitation": np.array([80.0, 60, 40]), "imitation_primitives": np.array([10.0, 20, 30])},
                 {"imitation": np.array([1, 2, 3]), "imitation_primitives": np.array([1, 2, 3])},
                 {"imitation": np.array([80.0, 60, 40]), "imitation_primitives": np.array([10.0, 20, 30])},
                 250)  # fmt: skip
    zero = replace(q3, condition=wp.Q3_VALUES["0"])
    tests = {
        (t.name.split(":")[0], t.endpoint): t for t in wp.transfer_cost_tests([q3, zero], [q1])
    }
    assert len(tests) == 6
    assert tests["eq. 2", "greedy"].difference == pytest.approx(0.0)
    assert (tests["eq. 2", "greedy"].wins, tests["eq. 2", "greedy"].losses) == (1, 1)
    assert tests["eq. 1", "greedy"].difference == pytest.approx(20.0)
    assert tests["eq. 1", "first_goal"].p == 1.0  # the same first goals: all ties
    with pytest.raises(ValueError, match="differ from Q1"):
        wp.transfer_cost_tests([q3], [replace(q1, budget=2000)])


def test_the_preset_rule_takes_the_highest_minimum_and_breaks_near_ties_by_early_goals(analysis):
    sys.path.insert(0, str(HERE))
    try:
        import choose_preset
    finally:
        sys.path.remove(str(HERE))
    # minima: a 80.0 (at y), b 80.5 (at x), c 70.0: a and b tie within 1 point, a has more
    # early goals (10 + 30 = 40 against 35), so a wins though b's minimum is higher
    table = {
        "a": {"x": (90.0, 10.0, 20), "y": (80.0, 30.0, 20)},
        "b": {"x": (80.5, 20.0, 20), "y": (95.0, 15.0, 20)},
        "c": {"x": (70.0, 99.0, 20), "y": (99.0, 99.0, 20)},
    }
    winner, scores = choose_preset.choose(table)
    assert winner == "a"
    assert (scores["a"]["minimum"], scores["a"]["at"], scores["a"]["early_goals"]) == (
        80.0,
        "y",
        40.0,
    )
    assert [c for c, s in scores.items() if s["tied_with_best"]] == ["a", "b"]
    # with no tolerance the highest minimum alone decides
    assert choose_preset.choose(table, tolerance=0.0)[0] == "b"
    with pytest.raises(ValueError, match="conditions differ"):
        choose_preset.choose({"a": {"x": (1.0, 1.0, 20)}, "b": {"y": (1.0, 1.0, 20)}})


@pytest.mark.slow
def test_the_committed_choice_regenerates_and_is_the_registered_preset(analysis):
    """The preset's choice, read again from the committed records, picks the candidate the
    record names, and the preset registered under its name is that candidate's settings."""
    import json

    from himit_torch.learner.presets import PRESETS

    sys.path.insert(0, str(HERE))
    try:
        import choose_preset
    finally:
        sys.path.remove(str(HERE))
    results = HERE.parent / "results" / "hierarchy"
    record = json.loads((results / "preset_choice.json").read_text())
    winner, scores = choose_preset.choose(choose_preset.read_table(results))
    assert winner == record["winner"]
    for candidate, score in scores.items():
        assert score["minimum"] == pytest.approx(record["candidates"][candidate]["minimum"])
    base = PRESETS[choose_preset.CANDIDATES[winner]].changes()
    registered = PRESETS[record["registered_as"]].changes()
    assert registered == {**base, "mentor_segments": True, "mentor_trial": True}


def _write_rows(directory, rows):
    """A tiny sweep record from ``rows`` (dicts with the columns that matter, ``goals`` the
    goals of a window ending at 75k, inside exp1's quarter; each run also has a window at
    80k with 100 goals, after it)."""
    import csv
    import json

    directory.mkdir(parents=True)
    extra = [k for k in rows[0] if k not in ("goals",)]
    with (directory / "runs.csv").open("w", newline="") as f:
        w = csv.DictWriter(f, extra)
        w.writeheader()
        w.writerows({k: r[k] for k in extra} for r in rows)
    with (directory / "results.csv").open("w", newline="") as f:
        keys = [k for k in extra if k not in ("greedy_percent_of_optimal", "first_goal_step")]
        w = csv.DictWriter(f, [*keys, "step", "goals_in_window"])
        w.writeheader()
        for r in rows:
            base = {k: r[k] for k in keys}
            w.writerow({**base, "step": 75_000, "goals_in_window": r["goals"]})
            w.writerow({**base, "step": 80_000, "goals_in_window": 100})
    (directory / "sweep.json").write_text(json.dumps({"commit": ["abcdef123", "abcdef9"]}))


def test_q3s_multi_room_sweep_is_split_by_initial_value_and_costed_against_trial_on(
    analysis, tmp_path
):
    """Hand-made records of the multi-room transfer sweep (4 learners, initial values −1 and 0)
    and of H3's trial sweep (trial on and off). Hand-solved: at −1 under the paper's schedule
    eq. 2 70 against options only 50, eq. 1 40 against primitives only 30, so hierarchy's
    effect 20 − 10 = 10; at 0 every value is 5 higher (the same split). Transfer's cost uses
    the trial-on cell only: eq. 2 70 − 80 = −10 (trial off's 0 is never read)."""
    _, wp = analysis
    greedy = {"imitation": 70, "options": 50, "imitation_primitives": 40, "primitives": 30}
    rows = [
        {"agent": a, "seed": s, "preset": p, "learner.initial_value": iv,
         "greedy_percent_of_optimal": g + (5 if iv == "0.0" else 0), "first_goal_step": 1000 + s,
         "goals": g // 10}
        for p in ("paper", "explore-goals") for iv in ("-1.0", "0.0")
        for a, g in greedy.items() for s in (0, 1)
    ]  # fmt: skip
    _write_rows(tmp_path / "q3_multirooms_exp1", rows)
    cells, own, missing = wp.load_q3_sweep_cells(tmp_path)
    assert missing == ["trial_exp1"] and own == []
    trial = [
        {"agent": a, "seed": s, "preset": p, "learner.mentor_trial": t,
         "greedy_percent_of_optimal": 80 if t == "True" else 0, "first_goal_step": 900,
         "goals": 3}
        for p in ("paper", "explore-goals") for t in ("False", "True")
        for a in ("imitation", "imitation_primitives") for s in (0, 1)
    ]  # fmt: skip
    _write_rows(tmp_path / "trial_exp1", trial)
    cells, own, missing = wp.load_q3_sweep_cells(tmp_path)
    assert missing == []
    assert [(c.condition, c.schedule) for c in cells] == [
        (wp.Q3_VALUES[v], p) for v in ("-1", "0") for p in ("paper", "explore-goals")
    ]
    for cell in cells:
        assert cell.task == "exp1_top_right" and cell.budget == 300_000
        assert cell.seeds == (0, 1) and cell.commit == "abcdef1, abcdef9"
        assert cell.goals_q1["imitation"].tolist() == [7, 7]  # (the 80k window is not counted)
        tests = {(t.name, t.endpoint): t for t in wp.cell_tests("Q3", cell)}
        assert tests[wp.HIERARCHY, "greedy"].difference == pytest.approx(10.0)
    assert wp.label("exp1_top_right").startswith("exp1, 80×80")
    assert [(c.task, c.schedule) for c in own] == [
        ("trial_exp1_own", "paper"),
        ("trial_exp1_own", "explore-goals"),
    ]
    assert own[0].greedy["imitation"].tolist() == [80, 80]
    cost = {(t.name.split(":")[0], t.schedule, t.endpoint): t
            for t in wp.transfer_cost_tests(cells, own)}  # fmt: skip
    assert len(cost) == 2 * 2 * 3  # only initial value −1's cells: imitator × schedule × endpoint
    assert cost["eq. 2", "paper", "greedy"].difference == pytest.approx(-10.0)
    assert cost["eq. 1", "paper", "greedy"].difference == pytest.approx(-40.0)


def _write_box_cell(directory, agents, greedy_values=(0.5, 0.25), first=(300, -1), window=5000):
    """A tiny puzzle-box cell as ``puzzle_box_round.py`` writes it: 20,000 steps (the quarter
    ends at 5,000), V*(start) = 0.5, seeds 0 and 1; openings 3 and 4 in the first window, 10 in
    each later one."""
    import csv
    import json

    (directory / "batches").mkdir(parents=True)
    (directory / "config.json").write_text(json.dumps({"window": window}))
    (directory / "commit.txt").write_text("abcdef123456\n")
    for agent in agents:
        runs = [{"seed": s, "first_opening": f, "openings": 7, "greedy_value": v}
                for s, f, v in zip((0, 1), first, greedy_values)]  # fmt: skip
        record = {"agent": agent, "steps": 20_000, "value_star": 0.5, "runs": runs}
        (directory / "batches" / f"{agent}.json").write_text(json.dumps(record))
        with (directory / "batches" / f"{agent}.csv").open("w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["batch", "seed", "step", "openings", "epsilon"])
            for step in (5000, 10_000, 15_000, 20_000):
                for seed in (0, 1):
                    w.writerow([agent, seed, step, 3 + seed if step == 5000 else 10, 0.75])


def test_a_box_cells_endpoint_1_is_its_greedy_value_minus_the_optimum(analysis, tmp_path):
    """Hand-solved: greedy values 0.5 and 0.25 against V*(start) = 0.5 give 0 and −0.25; the
    openings of the first quarter (5,000 of 20,000 steps) are the first window's, 3 and 4; a run
    that never opened keeps −1."""
    _, wp = analysis
    _write_box_cell(tmp_path / "cell", ("imitation", "options"))
    cell = wp.load_box_cell(tmp_path / "cell", "puzzlebox4", "paper")
    assert (cell.budget, cell.quarter_steps, cell.seeds, cell.commit) == (
        20_000,
        5000,
        (0, 1),
        "abcdef1",
    )
    assert cell.greedy["imitation"].tolist() == pytest.approx([0.0, -0.25])
    assert cell.first_goal["options"].tolist() == [300, -1]
    assert cell.goals_q1["imitation"].tolist() == [3.0, 4.0]
    assert wp.label("puzzlebox4") == "Puzzle box, 4 skewers"
    assert wp.box_cell_complete(tmp_path / "cell", ("imitation", "options"))
    assert not wp.box_cell_complete(tmp_path / "cell")  # eq. 1 and primitives only not run
    assert wp.endpoint_name("puzzlebox4", "greedy") == wp.BOX_GREEDY
    assert wp.endpoint_name("taxi", "greedy") == wp.ENDPOINTS["greedy"]


def test_a_box_cell_whose_learners_differ_in_seeds_is_refused(analysis, tmp_path):
    import json

    _, wp = analysis
    _write_box_cell(tmp_path / "cell", ("imitation", "options"))
    path = tmp_path / "cell" / "batches" / "options.json"
    record = json.loads(path.read_text())
    record["runs"][1]["seed"] = 5
    path.write_text(json.dumps(record))
    with pytest.raises(ValueError, match="seeds or budgets differ"):
        wp.load_box_cell(tmp_path / "cell", "puzzlebox4", "paper")


def test_a_box_run_is_changed_where_a_window_or_its_final_greedy_value_differs(analysis, tmp_path):
    """Three records of eq. 2: the same; seed 1's final greedy value moved; seed 0's first
    window's openings moved. Each changes exactly the run it touches."""
    import csv

    _, wp = analysis
    _write_box_cell(tmp_path / "base", ("imitation",))
    _write_box_cell(tmp_path / "same", ("imitation",))
    _write_box_cell(tmp_path / "value", ("imitation",), greedy_values=(0.5, 0.3))
    _write_box_cell(tmp_path / "window", ("imitation",))
    path = tmp_path / "window" / "batches" / "imitation.csv"
    with path.open() as f:
        rows = list(csv.reader(f))
    rows[1][3] = "9"  # seed 0, the first window
    with path.open("w", newline="") as f:
        csv.writer(f).writerows(rows)
    base = wp.box_window_records(tmp_path / "base")
    assert wp.runs_changed(base, wp.box_window_records(tmp_path / "same")) == (0, 2)
    value = wp.box_window_records(tmp_path / "value")
    assert wp.runs_changed(base, value) == (1, 2)
    assert value["imitation", 0] == base["imitation", 0]
    window = wp.box_window_records(tmp_path / "window")
    assert wp.runs_changed(base, window) == (1, 2)
    assert window["imitation", 1] == base["imitation", 1]


def test_the_box_cells_are_checked_run_by_run_against_h2s_record(analysis, tmp_path):
    """H2's `puzzlebox_trial` record holds eq. 2's runs for seeds 0 and 1; the new cell's seed 0
    equals it, seed 1's openings differ: 1 of 2 equal. Options only has no H2 batch here: left
    out."""
    import json

    _, wp = analysis
    _write_box_cell(tmp_path / "q1_puzzlebox4_paper", ("imitation", "options"))
    mine = json.loads((tmp_path / "q1_puzzlebox4_paper" / "batches" / "imitation.json").read_text())
    theirs = [dict(r) for r in mine["runs"]]
    theirs[1]["openings"] = 8
    (tmp_path / "puzzlebox_trial").mkdir()
    summary = {"batches": [{"batch": "speed_imitation", "runs": theirs}]}
    (tmp_path / "puzzlebox_trial" / "summary.json").write_text(json.dumps(summary))
    assert wp.box_h2_check(tmp_path, "q1_puzzlebox4_paper") == [("imitation", 1, 2)]
    assert wp.box_h2_check(tmp_path, "q1_taxi_paper") == []


def _write_discovery(directory, greedy, commit="1234567abcdef"):
    """A tiny ``himit run discovery`` record: runs.csv (the six learners, seeds 0 and 1),
    curves.csv (a window ending at 75k, inside exp1's quarter, with greedy // 10 goals, and one
    at 80k with 100, after it) and the page's commit line."""
    import csv

    directory.mkdir(parents=True)
    agents = {**greedy, "doorway_options": 99, "doorway_imitation": 99}
    with (directory / "runs.csv").open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["world", "agent", "seed", "first_goal_step", "total_goals",
                    "greedy_percent_of_optimal", "discovered_options"])  # fmt: skip
        for agent, g in agents.items():
            for seed in (0, 1):
                w.writerow(["exp1", agent, seed, 1000 + seed, g // 10 + 100, f"{g:.4f}",
                            3 if agent.startswith("discovered") else ""])  # fmt: skip
    with (directory / "curves.csv").open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["world", "agent", "seed", "step", "goals_in_window"])
        for agent, g in agents.items():
            for seed in (0, 1):
                w.writerow(["exp1", agent, seed, 75_000, g // 10])
                w.writerow(["exp1", agent, seed, 80_000, 100])
    (directory / "results.md").write_text(f"Runs recorded at commit `{commit}` (the code)\n")


def test_q3s_discovered_options_take_eq2s_and_options_onlys_places(analysis, tmp_path):
    """Hand-made discovery records (initial values −1 and 0, both schedules). Hand-solved: the
    discovered imitator 70 against discovered options only 50 (imitation effect +20), eq. 1 40
    against primitives only 30 (+10), so hierarchy's effect +10 and the discovered options' own
    effect 50 − 30 = +20; the hand-built doorway runs (99) are read by no contrast; goals in the
    first quarter are the 75k window's only (7 for the discovered imitator). The mechanism is
    the discovered imitator's only: its effect at 0 (+25, the record at 0 has it 5 higher)
    − at −1 (+20) = +5."""
    _, wp = analysis
    greedy = {"discovered_imitation": 70, "discovered_options": 50,
              "imitation_primitives": 40, "primitives": 30}  # fmt: skip
    for value in ("-1", "0"):
        for schedule in ("paper", "explore-goals"):
            shown = {**greedy, "discovered_imitation": 75} if value == "0" else greedy
            _write_discovery(tmp_path / f"q3_discovered_exp1_iv{value}_{schedule}", shown)
    cells, missing = wp.load_q3_discovered_cells(tmp_path)
    assert missing == [] and len(cells) == 4
    task = "exp1_top_right_discovered"
    for cell in cells:
        assert (cell.task, cell.budget, cell.commit, cell.seeds) == (task, 300_000, "1234567",
                                                                      (0, 1))  # fmt: skip
        assert set(cell.greedy) == {"imitation", "options", "imitation_primitives", "primitives"}
        assert cell.goals_q1["imitation"].tolist() in ([7, 7], [7.0, 7.0])
        tests = {(t.name, t.endpoint): t for t in wp.cell_tests("Q3", cell)}
        assert tests[wp.OWN, "greedy"].difference == pytest.approx(20.0)
        if cell.condition == wp.Q3_VALUES["-1"]:
            assert tests[wp.HIERARCHY, "greedy"].difference == pytest.approx(10.0)
    assert wp.label(task) == "exp1, 80×80, mentor's goal the top-right corner, discovered options"
    mechanism = wp.mechanism_tests(cells)
    by = {(t.name, t.schedule, t.endpoint): t for t in mechanism}
    assert by["eq. 2's " + wp.MECHANISM, "paper", "greedy"].difference == pytest.approx(5.0)
    assert by["eq. 1's " + wp.MECHANISM, "paper", "greedy"].difference == pytest.approx(0.0)
    assert wp.transfer_cost_tests(cells, []) == []  # (no own-task cell for discovered options)
    (tmp_path / "q3_discovered_exp1_iv0_paper" / "runs.csv").unlink()
    assert wp.load_q3_discovered_cells(tmp_path)[1] == ["q3_discovered_exp1_iv0_paper"]


def test_a_discovery_records_primitives_runs_are_checked_against_the_committed_sweep(
    analysis, tmp_path
):
    """The committed sweep's eq. 1 runs at −1 under the paper's schedule: seed 0 as the
    discovery record has it (first goal 1000, 107 goals, 40 %), seed 1 with other total goals
    (so 1 of 2 equal); the sweep's initial-value-0 rows and other schedule are not compared."""
    _, wp = analysis
    _write_discovery(tmp_path / "d", {"discovered_imitation": 70, "discovered_options": 50,
                                      "imitation_primitives": 40, "primitives": 30})  # fmt: skip
    rows = [
        {"agent": a, "seed": s, "preset": p, "learner.initial_value": iv,
         "first_goal_step": 1000 + s, "total_goals": 104 if (a, s) == ("primitives", 1) else
         {"imitation_primitives": 104, "primitives": 103}[a], "greedy_percent_of_optimal":
         {"imitation_primitives": "40.0", "primitives": "30.00001"}[a], "goals": 1}
        for p in ("paper", "explore-goals") for iv in ("-1.0", "0.0")
        for a in ("imitation_primitives", "primitives") for s in (0, 1)
    ]  # fmt: skip
    _write_rows(tmp_path / "sweep", rows)
    assert wp.summaries_equal(tmp_path, "d", "sweep", ("imitation_primitives",), "-1",
                              "paper") == (2, 2)  # fmt: skip
    # primitives: seed 0's greedy 30.00001 rounds to 30.0000 (equal), seed 1's goals differ
    assert wp.summaries_equal(tmp_path, "d", "sweep", ("primitives",), "-1", "paper") == (1, 2)
    assert wp.summaries_equal(tmp_path, "d", "absent", ("primitives",), "-1", "paper") == (0, 0)


def test_f_on_q2_compares_each_n_with_q2s_eq2_cell_and_counts_changed_runs(analysis, tmp_path):
    """exp2 at the option ends (budget 200k: the quarter ends at 50k). Trial alone (Q2's cell):
    eq. 2 greedy 80 and 90, goals 5 and 7 in the 50k window. N = 1: seed 1's 50k window has 8
    goals (changed; greedy 92): 1 of 2 runs changed, goals +0.5, greedy +1.0; N = 3: the same
    records (0 of 2). The records absent (a stride's sweeps, MiniGrid's cells) are named."""
    import csv
    import json

    _, wp = analysis

    def write(name, rows, extra=()):
        directory = tmp_path / name
        directory.mkdir()
        head = ["agent", "seed", "preset", *extra]
        with (directory / "runs.csv").open("w", newline="") as f:
            w = csv.writer(f)
            w.writerow([*head, "greedy_percent_of_optimal", "first_goal_step"])
            for r in rows:
                w.writerow([*r[: len(head)], r[-2], 1000])
        with (directory / "results.csv").open("w", newline="") as f:
            w = csv.writer(f)
            w.writerow([*head, *wp.SWEEP_RECORD_COLUMNS])
            for r in rows:
                w.writerow([*r[: len(head)], 50_000, r[-1], "0.1", 3, 10, 20, "0.5"])
        (directory / "sweep.json").write_text(json.dumps({"commit": "fedcba987"}))

    write("q2_ends_exp2", [("imitation", 0, "paper", 80, 5), ("imitation", 1, "paper", 90, 7)])
    write("f_q2_ends_exp2", [("imitation", 0, "paper", 1, 80, 5), ("imitation", 1, "paper", 1, 92, 8),
                             ("imitation", 0, "paper", 3, 80, 5), ("imitation", 1, "paper", 3, 90, 7)],
          extra=("learner.mentor_feasibility",))  # fmt: skip
    trial = wp.Cell("exp2", "paper", 200_000, "fedcba9", (0, 1),
                    {wp.EQ2: np.array([80.0, 90.0])}, {wp.EQ2: np.array([1000, 1000])},
                    {wp.EQ2: np.array([5.0, 7.0])}, 50_000, "option ends")  # fmt: skip
    stride = replace(trial, condition="stride 10")  # (its records absent: named, no row)
    tests, rows, missing = wp.f_q2_section(tmp_path, [trial, stride])
    assert missing == ["f_q2_stride_exp2", "q2_stride_exp2"]
    assert rows == [
        "| exp2, 40×40, option ends | ε per decision (paper) | N = 1 | 1 of 2 |",
        "| exp2, 40×40, option ends | ε per decision (paper) | N = 3 | 0 of 2 |",
    ]
    by = {(t.name, t.endpoint): t for t in tests}
    assert by["N = 1 − trial alone", "greedy"].difference == pytest.approx(1.0)
    assert by["N = 1 − trial alone", "goals_q1"].difference == pytest.approx(0.5)
    assert by["N = 3 − trial alone", "greedy"].difference == pytest.approx(0.0)
    assert {t.condition for t in tests} == {"option ends"}
    # at a stride only that stride's rows count: stride 10 unchanged at N = 1 (greedy 80, 90),
    # stride 20's rows (greedy 0, other goals) never read; N = 3 at stride 10 changes seed 0
    write("q2_stride_exp2", [("imitation", s, "paper", k, g, q) for s, g, q in ((0, 80, 5),
                             (1, 90, 7)) for k in (10, 20)], extra=("observation_stride",))  # fmt: skip
    write("f_q2_stride_exp2", [("imitation", s, "paper", k, n, 0 if k == 20 else g, 9 if
                                (k, n, s) == (10, 3, 0) else q)
                               for s, g, q in ((0, 80, 5), (1, 90, 7)) for k in (10, 20)
                               for n in (1, 3)],
          extra=("observation_stride", "learner.mentor_feasibility"))  # fmt: skip
    tests, rows, missing = wp.f_q2_section(tmp_path, [stride])
    assert missing == [] and rows == [
        "| exp2, 40×40, stride 10 | ε per decision (paper) | N = 1 | 0 of 2 |",
        "| exp2, 40×40, stride 10 | ε per decision (paper) | N = 3 | 1 of 2 |",
    ]
    by = {(t.name, t.endpoint): t for t in tests}
    assert by["N = 1 − trial alone", "greedy"].difference == pytest.approx(0.0)
    assert by["N = 3 − trial alone", "goals_q1"].difference == pytest.approx(2.0)  # (9 − 5) / 2
    doorkey = replace(trial, task="doorkey5x5")
    assert wp.f_q2_section(tmp_path, [doorkey, replace(doorkey, condition="stride 20")])[2] == [
        *(f"f_q2_doorkey5x5_ends_paper_n{n}" for n in (1, 3)),
        *(f"f_q2_doorkey5x5_stride20_paper_n{n}" for n in (1, 3)),
    ]
