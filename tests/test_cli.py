"""The ``himit`` command line, run in-process with tiny budgets."""

import re
import subprocess
import sys

import numpy as np
import pytest

from himit_torch.cli import COMMANDS, main
from himit_torch.exact.option_models import option_durations, option_models
from himit_torch.exact.planning import expected_steps, smdp_value_iteration
from himit_torch.mentor.demonstrations import Demonstrations
from himit_torch.options.builders import primitive_options
from himit_torch.worlds.multirooms import MultiRooms


def table_row(out: str, label: str) -> tuple[float, float]:
    """``(steps, goals)`` from the info table's row starting with ``label``."""
    match = re.search(rf"^{re.escape(label)}.*?≈?([\d.]+)\s+([\d.]+)\s*$", out, flags=re.M)
    assert match, f"no row {label!r} in:\n{out}"
    return float(match.group(1)), float(match.group(2))


def run_ok(capsys, argv) -> str:
    assert main(argv) == 0
    captured = capsys.readouterr()
    assert captured.err == ""
    return captured.out


def run_error(capsys, argv) -> str:
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("himit: error: "), err
    assert "Traceback" not in err
    return err


# ------------------------------------------------------------------------------------ info
def test_info_experiment_2_matches_the_paper(capsys):
    out = run_ok(capsys, ["info", "--size", "40", "--rooms", "10"])
    paper_steps, paper_goals = table_row(out, "paper, experiment 2")
    assert paper_goals == 53.2
    for label in ("primitives only", "learner's options", "mentor"):
        steps, goals = table_row(out, label)
        assert steps == pytest.approx(paper_steps, rel=0.10)
        assert goals == pytest.approx(paper_goals, rel=0.10)
        assert goals == pytest.approx(5000 / steps, abs=0.06)  # both rounded to 0.1
    assert "states     1600" in out and "doorways 180" in out and "rooms 100" in out
    assert re.search(r"learner\s+364 options \(4 primitive, 360 doorway", out)


def test_info_small_world_is_exact(capsys):
    out = run_ok(capsys, ["info", "--size", "20", "--rooms", "2", "--slip", "0.2"])
    world = MultiRooms(size=20, rooms=2, slip=0.2)
    prims = primitive_options(world)
    policy = smdp_value_iteration(option_models(world, prims)).policy
    steps = expected_steps(
        option_durations(world, prims), policy, world.start_state, world.terminal_mask
    )
    assert table_row(out, "primitives only") == (round(steps, 1), round(5000 / steps, 1))
    assert "slip 0.2" in out and "states     400" in out
    assert "paper" not in out  # not one of the paper's worlds


@pytest.mark.parametrize(
    "flags, learner",
    [
        ([], "12 options (4 primitive, 8 doorway"),
        (["--corner-options"], "44 options (4 primitive, 8 doorway, 32 corner"),
        (["--no-doorway-options"], "4 options (4 primitive;"),
        (["--no-doorway-options", "--corner-options"], "36 options (4 primitive, 32 corner"),
    ],
)
def test_info_option_sets(capsys, flags, learner):
    out = run_ok(capsys, ["info", "--size", "12", "--rooms", "2", *flags])
    assert re.search(r"^learner\s+" + re.escape(learner), out, flags=re.M), out
    steps, _ = table_row(out, "learner's options")
    prim_steps, _ = table_row(out, "primitives only")
    assert steps >= prim_steps - 0.05  # options never beat the flat optimum


# ---------------------------------------------------------------------------------- errors
@pytest.mark.parametrize(
    "argv, what",
    [
        (["info", "--size", "x"], "argument --size: invalid int value"),
        (["info", "--size", "10", "--rooms", "3"], "size=10 is not a multiple of rooms=3"),
        (["info", "--slip", "1.5"], "slip=1.5 must lie in [0, 1)"),
        (["demo", "--episodes", "0"], "argument --episodes: must be ≥ 1"),
        (["run", "exp2", "--agents", "psrl"], "argument --agents: invalid choice: 'psrl'"),
        (["run", "discovery", "--agents", "options_psrl"], "takes no --agents"),
        (["bogus"], "invalid choice: 'bogus'"),
        ([], "the following arguments are required: command"),
    ],
)
def test_user_mistakes_are_one_line_and_exit_2(capsys, argv, what):
    assert what in run_error(capsys, argv)


def test_help_exits_0(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    assert all(name in out for name in COMMANDS)


def test_version_is_the_package_version(capsys):
    """`himit --version` prints the one version there is: the package's, which is also the
    distribution's (pyproject.toml reads it from himit_torch.__version__)."""
    import himit_torch

    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.strip() == f"himit {himit_torch.__version__}"
    assert re.fullmatch(r"\d+\.\d+\.\d+(\.dev\d+|rc\d+)?", himit_torch.__version__)


# ------------------------------------------------------------------------------------ demo
def test_demo_writes_demonstrations_and_figure(capsys, tmp_path):
    out_dir = tmp_path / "demo"
    out = run_ok(
        capsys, ["demo", "--out", str(out_dir), "--episodes", "2", "--seed", "3", "--steps", "0"]
    )
    npz, png = out_dir / "demonstrations.npz", out_dir / "world_mentor.png"
    assert str(npz) in out and str(png) in out
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 5000
    demos = Demonstrations.load(npz, world=MultiRooms(size=40, rooms=10))
    assert demos.num_episodes == 2
    assert all(e[0] == 0 and e[-1] == 40 * 40 - 1 for e in demos.episodes)
    with np.load(npz) as f:
        assert sorted(f.files) == ["episode_starts", "format_version", "states", "world"]


def test_demo_is_deterministic_per_seed(capsys, tmp_path):
    for name, seed in (("a", "5"), ("b", "5"), ("c", "6")):
        run_ok(
            capsys,
            [
                "demo",
                "--out",
                str(tmp_path / name),
                "--episodes",
                "2",
                "--seed",
                seed,
                "--steps",
                "0",
            ],
        )
    a, b, c = (np.load(tmp_path / n / "demonstrations.npz")["states"] for n in "abc")
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)


# ------------------------------------------------------------------------ Gymnasium worlds
def test_info_of_a_gymnasium_world_is_exact(capsys):
    """CliffWalking's optimum: 13 steps along the cliff, V* = −Σ_{k<13} 0.99^k."""
    out = run_ok(capsys, ["info", "--env", "cliffwalking"])
    assert "states     48 (start states 1, terminal 1, goal 1)" in out
    assert "to top-left (0,0), to top-right (0,11)" in out
    assert f"V*(start distribution)      {-(1 - 0.99**13) / 0.01:.3f}" in out
    assert re.search(r"steps per episode\s+13\.0\n", out) and re.search(
        r"goals per 5000 steps\s+384\.6", out
    )
    out = run_ok(
        capsys, ["info", "--env", "FrozenLake-v1", "--env-kwargs", '{"is_slippery": false}']
    )
    assert "(4 primitive)" in out and re.search(r"steps per episode\s+6\.0\n", out)


@pytest.mark.parametrize(
    "argv, what",
    [
        (
            ["info", "--env", "Nope-v0"],
            "from_gymnasium('Nope-v0'): gymnasium.make failed with NameNotFound",
        ),
        (["info", "--env", "CartPole-v1"], "Discrete observation and action spaces"),
        (["info", "--env", "taxi", "--env-kwargs", '{"is_rainy": true}'], "give --env Taxi-v4"),
        (["info", "--env", "Taxi-v4", "--env-kwargs", "[1]"], "must be a JSON object"),
        (["run", "gymnasium", "--resume"], "takes no --resume"),
    ],
)
def test_gymnasium_mistakes_are_one_line(capsys, argv, what):
    assert what in run_error(capsys, argv)


def _python_stdout(code: str) -> str:
    """What a fresh interpreter running ``code`` prints."""
    return subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout


@pytest.fixture(scope="module")
def loaded_by_a_fresh_parser() -> set[str]:
    """The modules a new interpreter has loaded after ``import himit_torch`` and building the
    CLI's parser (what every command does first): one interpreter (≈ 4 s) for the tests below."""
    code = (
        "import sys, himit_torch; from himit_torch.cli import build_parser; build_parser(); "
        "print(' '.join(sys.modules))"
    )
    return set(_python_stdout(code).split())


def test_building_the_parser_leaves_scipy_stats_unimported(loaded_by_a_fresh_parser):
    """``scipy.stats`` costs ~0.7 s to import; every command builds the parser (which imports the
    sweep's summary statistics), so :mod:`himit_torch.statistics` imports it at first use."""
    assert "scipy.stats" not in loaded_by_a_fresh_parser
    # ...and the statistics still work once it is needed
    from himit_torch.statistics import t_interval

    assert t_interval([1.0, 2.0, 3.0]).low < 2.0 < t_interval([1.0, 2.0, 3.0]).high


def test_importing_the_package_leaves_numba_and_networkx_unimported(loaded_by_a_fresh_parser):
    """Numba (≈ 0.5 s) is imported by what compiles (the engine, the exact option models, the
    option builders' search) and networkx (≈ 0.2 s) by what builds a mentor graph, each at first
    use: ``import himit_torch`` and building the CLI's parser load neither."""
    assert not {"numba", "networkx"} & loaded_by_a_fresh_parser
    # ...and the fixture does see a module that is loaded
    assert {"torch", "himit_torch.cli"} <= loaded_by_a_fresh_parser


def _freeze_count_at_exit(call: str) -> int:
    """How many objects a fresh interpreter had frozen out of the garbage collector when its
    exit handlers ran, after ``call`` (a handler registered first runs last)."""
    code = (
        "import atexit, gc, sys\n"
        "atexit.register(lambda: sys.stdout.write(f'frozen {gc.get_freeze_count()}\\n'))\n"
        "from himit_torch.cli import main\n"
        f"{call}\n"
    )
    return int(re.search(r"^frozen (\d+)$", _python_stdout(code), flags=re.M).group(1))


# (three fresh interpreters, ≈ 13 s: CI's)
@pytest.mark.slow
def test_a_command_leaves_its_objects_out_of_the_exit_collections():
    """The interpreter's last garbage collections walked every object a command left (≈ 1 s
    after a ``himit run``): :func:`main` freezes them at exit, once per process, and so does
    each process of a pool of worlds."""
    assert _freeze_count_at_exit("main(['info', '--size', '20', '--rooms', '2'])") > 10_000
    assert _freeze_count_at_exit("pass") == 0  # (no command, no freeze)
    # each world process of `himit run paper`'s pool too (the run waits for them to end)
    pool_process = "from himit_torch.runs.pool import _pool_process; _pool_process(1)"
    assert _freeze_count_at_exit(pool_process) > 10_000
