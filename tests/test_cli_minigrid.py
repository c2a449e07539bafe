"""``himit info --minigrid ID``: a MiniGrid task's summary, and its refusals on the command line."""

from __future__ import annotations

import re

import pytest

pytest.importorskip("minigrid")

import himit_torch as ht  # noqa: E402
from himit_torch.cli import main  # noqa: E402


def test_info_minigrid(capsys):
    assert main(["info", "--minigrid", "MiniGrid-DoorKey-5x5-v0"]) == 0
    out = capsys.readouterr().out
    world = ht.from_minigrid("MiniGrid-DoorKey-5x5-v0")
    assert f"states     {world.num_states:,} reachable" in out
    assert "go to the yellow key, go to the yellow door, go to the goal" in out
    options = ht.primitive_options(world)
    plan = ht.smdp_value_iteration(ht.option_models(world, options))
    steps = ht.expected_steps(
        ht.option_durations(world, options), plan.policy, 0, world.terminal_mask
    )
    row = re.search(r"^primitives only\s+([\d.]+)\s+([\d.]+)$", out, flags=re.M)
    assert row and float(row.group(1)) == round(steps, 1)
    assert re.search(r"^mentor \(prefers its options within 0.01\)\s+[\d.]+\s+[\d.]+$", out, re.M)


@pytest.mark.parametrize(
    "argv, words",
    [
        (["--minigrid", "MiniGrid-Nope-v0"], "gymnasium.make failed"),
        (["--minigrid", "MiniGrid-Dynamic-Obstacles-5x5-v0"], "stochastic"),
        (["--minigrid", "MiniGrid-DoorKey-5x5-v0", "--env", "Taxi-v4"], "not both"),
        (["--minigrid", "MiniGrid-DoorKey-5x5-v0", "--puzzle-box", "2"], "not both"),
        (["--minigrid", "MiniGrid-DoorKey-5x5-v0", "--env-kwargs", "{}"], "is for --env"),
    ],
)
def test_info_minigrid_refused(capsys, argv, words):
    with pytest.raises(SystemExit) as exc:
        main(["info", *argv])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith("himit: error:") and words in err and err.count("\n") == 1
