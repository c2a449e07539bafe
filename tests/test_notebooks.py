"""The notebooks in ``notebooks/`` run top to bottom with tiny budgets (nbclient), in a kernel of
this very interpreter, and draw their figures."""

import sys
from pathlib import Path

import nbformat
import pytest

nbclient = pytest.importorskip("nbclient")

NOTEBOOKS = Path(__file__).resolve().parent.parent / "notebooks"


def execute(name: str, workdir: Path) -> nbformat.NotebookNode:
    """Run ``notebooks/<name>.ipynb`` in ``workdir`` and return it with its outputs; one cell is
    appended that reports the kernel's interpreter."""
    nb = nbformat.read(NOTEBOOKS / f"{name}.ipynb", as_version=4)
    nb.cells.append(nbformat.v4.new_code_cell("import sys; print(sys.prefix)"))
    # kernel.json says "python": jupyter_client runs it as sys.executable, this interpreter.
    # iopub_timeout: after a cell's reply, how long its outputs may take to arrive. nbclient's
    # 4 s default dropped them silently on a loaded machine (the last cell's print came back
    # empty); waited for longer here, and a timeout fails the test instead.
    client = nbclient.NotebookClient(
        nb,
        timeout=120,
        iopub_timeout=60,
        raise_on_iopub_timeout=True,
        kernel_name="python3",
        resources={"metadata": {"path": str(workdir)}},
    )
    client.execute()
    return nb


def outputs(nb: nbformat.NotebookNode, kind: str) -> list:
    return [
        o for c in nb.cells if c.cell_type == "code" for o in c.outputs if o.output_type == kind
    ]


@pytest.fixture
def tiny_budget(monkeypatch, tmp_path):
    monkeypatch.setenv("HIMIT_NOTEBOOK_STEPS", "400")
    monkeypatch.setenv("HIMIT_NOTEBOOK_SEEDS", "1")
    monkeypatch.delenv("HIMIT_NOTEBOOK_LOGDIR", raising=False)
    monkeypatch.setenv("MPLBACKEND", "module://matplotlib_inline.backend_inline")
    return tmp_path


# Each runs in a fresh kernel (≈ 6 s and more): all under -m slow (CI).
@pytest.mark.slow
@pytest.mark.parametrize(
    "name",
    [
        "quickstart",
        pytest.param("intrinsic_reward", marks=pytest.mark.slow),
        pytest.param("your_own_world", marks=pytest.mark.slow),
        pytest.param("option_discovery", marks=pytest.mark.slow),
        pytest.param("puzzle_box", marks=pytest.mark.slow),
        pytest.param("minigrid", marks=pytest.mark.slow),
    ],
)
def test_notebook_runs_with_a_tiny_budget(name, tiny_budget):
    earlier = tiny_budget / "runs/intrinsic_reward/tb/world40__known__seed0"
    if name == "intrinsic_reward":
        # An earlier execution with another budget left its events here; the notebook must
        # replace them, not append (the bug: one folder held 5000…100000, then 500…2000).
        from himit_torch import TensorBoardLogger

        old = TensorBoardLogger(earlier.parent, [earlier.name])
        for step in (5000, 10000):
            old.scalar(0, "charts/goals_in_window", 7.0, step)
        old.close()
    nb = execute(name, tiny_budget)
    assert not outputs(nb, "error")
    pngs = [o for o in outputs(nb, "display_data") if "image/png" in o.get("data", {})]
    assert pngs, f"{name}: no figure was drawn"
    streams = outputs(nb, "stream")
    last = [o["text"] for o in nb.cells[-1].outputs if o.output_type == "stream"]
    assert "".join(last).strip() == sys.prefix, "the kernel ran another interpreter"
    assert not [s for s in streams if s["name"] == "stderr"], (
        f"{name} wrote to stderr: {[s['text'][:300] for s in streams if s['name'] == 'stderr']}"
    )
    text = "".join(s["text"] for s in streams)
    if name == "quickstart":
        assert "364 options" in text and "first goal at step" in text
        assert "54.7 goals per 5000 steps" in text  # our exact optimum, computed
        assert text.count("steps in the goal's room") == 6  # the reach of every run, measured
    elif name == "option_discovery":
        assert "400 steps per run, warm-up 100, 1 seed(s), separation 3" in text
        assert "seed 0:" in text and "precision" in text and "20 episodes: precision" in text
        assert text.count("total goals per run") == 3  # all three learners ran
    elif name == "puzzle_box":
        assert "PuzzleBox(skewers=4, steps=4, slip=0.1, pinch_slip=0.1, S=8125, A=11)" in text
        # exact planning: both organisations, both styles, the optimum's value
        assert text.count("movements, V(start) = 0.153832") == 4
        assert text.count("first opening at step") == 3  # 3 conditions × 1 seed
        assert "{'plain': 20, 'any': 500} mapped episodes" in text
        assert "Beside Whiten" in text or "no committed results here" in text
    elif name == "your_own_world":
        assert "104 states; True for the TabularWorld protocol" in text
        assert "refused: Demonstrations: episode 0, index 2: state 50 follows 1" in text
        assert "Taxi-v4(S=500, A=6, start states=300" in text and "drive to B" in text
        assert "V* from the start distribution: 6.327" in text
        assert "first goal at step" in text and "deliveries per run" in text  # both batches ran
    elif name == "minigrid":
        assert "MiniGrid-DoorKey-6x6-v0(S=1294, A=6" in text
        assert text.count("14 steps start → goal") == 2  # exact: primitives, learner's options
        assert "mentor: 18 steps start → goal" in text
        assert "imitation run 0:" in text  # its greedy policy replayed in MiniGrid
    else:
        assert "8 runs × 400 steps" in text  # 8 variants × 1 seed, the tiny budget
        assert len(list((tiny_budget / "runs/intrinsic_reward/tb").glob("world40__*"))) == 8
        assert "cycle-safe: True" in text
        assert "20 of them into the goal" in text  # computed, not a hard-coded "all"
        # Every claim of "What we see" is checked by a cell (True/False at any budget).
        assert sum(line.strip().startswith(("True ", "False ")) for line in text.splitlines()) == 12
        from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

        acc = EventAccumulator(str(earlier))
        acc.Reload()
        assert [e.step for e in acc.Scalars("charts/goals_in_window")] == [100, 200, 300, 400]
