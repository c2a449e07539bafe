"""The CUDA path: the torch engine on a GPU takes the decisions of the compiled engine on the CPU.

Skipped without a CUDA device (CI has none); about a minute on one.

On a GPU, ``index_add_``/``scatter_add_`` on float64 add repeated indices with atomics in no
fixed order, so the ``Q`` and mentor caches, ``V`` and the sweep priorities differ from the CPU's
in the last bits (≤ ~1e-15 here). Each quantity compared is at most ~1e2 (values ≤ 1, caches
are counts × values), so ``VALUES_ATOL = 1e-9`` leaves six orders of magnitude for rounding
while a wrong operation (a lost or doubled update) moves a value by ≥ ~1e-3.

Why the horizons are short: prioritized sweeping is not continuous in its inputs. A sweep backs
up the ``n`` highest-priority states, ties to the lowest state, and stops at its budget; when
two priorities are equal on the CPU and one ulp apart on the GPU, another state is backed up
first and values move by ~1e-4 in one tick (measured on an H100: 12×12 world, default config,
drift ≤ 1e-15 until tick 1346, then 1.6e-4; first different decision at tick 3209; with
``plan_every=4, sweep_rounds=1`` the first different decision at tick 3442). Runs longer than
~1000 ticks are therefore equal only in distribution, not tick for tick, and even two CUDA runs
of one batch may differ. So the tests below check (a) 1000 ticks from the start, (b) 40 ticks
from exact CPU states taken late in a run (many edges, goals, mentor terms), and (c) a CUDA
checkpoint resumed on the CPU, each within that horizon.
"""

import pytest
import torch

from himit_torch import Learner, LearnerConfig, learner_options

pytestmark = pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")
pytest.importorskip("numba")

AGENT_MIX = ["imitation", "options", "primitives", "imitation_confident", "imitation_primitives"]
CONFIGS = {
    "default": LearnerConfig(window=1000),
    "plan_every4_one_round": LearnerConfig(window=1000, plan_every=4, sweep_rounds=1),
}
VALUES_ATOL = 1e-9
#: float64 tensors that hold counts (sums of ones: exact in any order) or ε (no sums): compared exactly
EXACT_FLOATS = {"epsilon", "row_count", "state_tries", "model.edge_count", "mentor.edge_count"}
TICKS = 1000  # one whole metrics window, inside the horizon where runs agree tick for tick


def _make(world, demos, config, device, engine) -> Learner:
    return Learner(
        world,
        learner_options(world),
        AGENT_MIX,
        range(len(AGENT_MIX)),
        config=config,
        demonstrations=demos,
        device=device,
        engine=engine,
    )


def _state(learner: Learner) -> dict[str, torch.Tensor]:
    """The learner's state, on the CPU."""
    run, cache = learner.run_state, learner.cache
    state = {
        "position": run.position,
        "row": run.row,
        "decisions": run.decisions,
        "goals": run.goals,
        "first_goal_step": run.first_goal_step,
        "epsilon": run.epsilon,
        "backups_done": run.backups_done,
        "visits": run.visits,
        "values": cache.values,
        "q_numerator": cache.q_numerator,
        "q_second": cache.q_second,
        "mentor_numerator": cache.mentor_numerator,
        "mentor_second": cache.mentor_second,
        "priority": learner.sweeper.queue.priority,
        "pending": learner.sweeper.pending,
        "row_count": learner.model.row_count,
        "state_tries": learner.model.state_tries,
    }
    for prefix, store in (("model", learner.model), ("mentor", learner.mentor)):
        E = int(store.num_edges.max())
        state[f"{prefix}.num_edges"] = store.num_edges
        for name in ("edge_row", "edge_successor", "edge_count"):
            state[f"{prefix}.{name}"] = getattr(store, name)[:, :E]
    return {name: value.cpu() for name, value in state.items()}


def assert_same_run(cpu: Learner, other: Learner) -> None:
    """Same decisions, goals, counts, edges and curves exactly; float64 state to VALUES_ATOL."""
    assert cpu.views.t == other.views.t
    a, b = _state(cpu), _state(other)
    for name in a:
        if a[name].dtype == torch.float64 and name not in EXACT_FLOATS:
            torch.testing.assert_close(
                b[name],
                a[name],
                atol=VALUES_ATOL,
                rtol=0,
                msg=lambda m, name=name: f"t={cpu.views.t} {name}: {m}",
            )
        else:
            assert torch.equal(a[name], b[name]), f"t={cpu.views.t} {name}"
    assert torch.equal(cpu.metrics.curve(), other.metrics.curve()), f"t={cpu.views.t} curve"


def _all_tensors(x):
    if isinstance(x, torch.Tensor):
        yield x
    elif isinstance(x, dict):
        for v in x.values():
            yield from _all_tensors(v)
    elif isinstance(x, (list, tuple)):
        for v in x:
            yield from _all_tensors(v)


@pytest.mark.parametrize("name", list(CONFIGS))
def test_cuda_torch_engine_matches_cpu_numba(world12, mentor_demos12, name):
    """Every agent variant, one window of 1000 ticks: the CUDA run is the CPU run."""
    cpu = _make(world12, mentor_demos12, CONFIGS[name], "cpu", "numba")
    gpu = _make(world12, mentor_demos12, CONFIGS[name], "cuda", "torch")
    assert gpu.views.state_values().is_cuda and gpu.engine.name == "torch"
    cpu.run(TICKS)
    gpu.run(TICKS)
    assert_same_run(cpu, gpu)
    assert int(cpu.views.decisions.min()) > 300 and int(cpu.views.goals.sum()) > 0
    # torch's counts on the GPU, numpy's on the CPU: the same shares
    assert torch.equal(gpu.views.model_coverage().cpu(), cpu.views.model_coverage())


@pytest.mark.parametrize("name", list(CONFIGS))
def test_cuda_ticks_from_late_cpu_states(world12, mentor_demos12, name):
    """From exact CPU states at ticks 1500 and 3000 (edge lists grown, goals found, mentor terms
    in play), 40 CUDA ticks are the CPU's 40 ticks."""
    cpu = _make(world12, mentor_demos12, CONFIGS[name], "cpu", "numba")
    gpu = _make(world12, mentor_demos12, CONFIGS[name], "cuda", "torch")
    for until in (1500, 3000):
        cpu.run(until - cpu.views.t)
        gpu.load_state_dict(cpu.state_dict())
        assert gpu.views.state_values().is_cuda and gpu.model.edge_row.is_cuda
        cpu.run(40)
        gpu.run(40)
        assert_same_run(cpu, gpu)
    assert int(cpu.views.goals.sum()) > 0


@pytest.mark.parametrize("name", list(CONFIGS))
def test_cuda_checkpoint_resumes_on_the_cpu(world12, mentor_demos12, name):
    """A CUDA learner's state_dict loads into a CPU (numba) learner, which goes on to the run an
    uninterrupted CPU run makes."""
    straight = _make(world12, mentor_demos12, CONFIGS[name], "cpu", "numba")
    straight.run(TICKS)
    gpu = _make(world12, mentor_demos12, CONFIGS[name], "cuda", "torch")
    gpu.run(400)
    resumed = _make(world12, mentor_demos12, CONFIGS[name], "cpu", "numba")
    resumed.load_state_dict(gpu.state_dict())
    assert not any(t.is_cuda for t in _all_tensors(resumed.state_dict()))
    resumed.run(TICKS - 400)
    assert resumed.engine.name == "numba"
    assert_same_run(straight, resumed)
