"""The CUDA path: the torch engine on a GPU takes the decisions of the compiled engine on the CPU.

Skipped without a CUDA device (CI has none). On a GPU, ``index_add_``/``scatter_add_`` on float64
add repeated indices with atomics in no fixed order, so the ``Q`` and mentor caches, ``V`` and the
sweep priorities may differ from the CPU's in the last bits. Decisions, goals, counts, edge lists
and curves must still be identical; float64 state is compared to ``VALUES_ATOL``: every such
quantity here is at most ~1e2 (values ≤ 1, caches are counts × values), one reordered addition
moves it by ≤ ~1e2 · 2⁻⁵³ ≈ 1e-14, and a run of a few thousand ticks makes ~1e5 of them per
batch, so honest reordering stays orders of magnitude below 1e-9, while a wrong operation (a lost
or doubled update) moves a value by ≥ ~1e-3.
"""
import pytest
import torch

from himit_torch import (Learner, LearnerConfig, MultiRooms, learner_options, mentor_options,
                         mentor_policy, record_demonstrations)

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
TICKS = 3000


@pytest.fixture(scope="module")
def world12() -> MultiRooms:
    return MultiRooms(12, 2)


@pytest.fixture(scope="module")
def demos12(world12):
    return record_demonstrations(world12, mentor_policy(world12, mentor_options(world12)), 5, seed=0)


def _make(world, demos, config, device, engine) -> Learner:
    return Learner(world, learner_options(world), AGENT_MIX, range(len(AGENT_MIX)), config=config,
                   demonstrations=demos, device=device, engine=engine)


def _state(learner: Learner) -> dict[str, torch.Tensor]:
    """The learner's state, on the CPU."""
    run, cache = learner.run_state, learner.cache
    state = {"position": run.position, "row": run.row, "decisions": run.decisions,
             "goals": run.goals, "first_goal_step": run.first_goal_step, "epsilon": run.epsilon,
             "backups_done": run.backups_done, "visits": run.visits, "values": cache.values,
             "q_numerator": cache.q_numerator, "q_second": cache.q_second,
             "mentor_numerator": cache.mentor_numerator, "mentor_second": cache.mentor_second,
             "priority": learner.sweeper.queue.priority, "pending": learner.sweeper.pending,
             "row_count": learner.model.row_count, "state_tries": learner.model.state_tries}
    for prefix, store in (("model", learner.model), ("mentor", learner.mentor)):
        E = int(store.num_edges.max())
        state[f"{prefix}.num_edges"] = store.num_edges
        for name in ("edge_row", "edge_successor", "edge_count"):
            state[f"{prefix}.{name}"] = getattr(store, name)[:, :E]
    return {name: value.cpu() for name, value in state.items()}


def assert_same_run(cpu: Learner, gpu: Learner) -> None:
    """Same decisions, goals, counts, edges and curves exactly; float64 state to VALUES_ATOL."""
    assert cpu.t == gpu.t
    a, b = _state(cpu), _state(gpu)
    for name in a:
        if a[name].dtype == torch.float64 and name not in EXACT_FLOATS:
            torch.testing.assert_close(b[name], a[name], atol=VALUES_ATOL, rtol=0,
                                       msg=lambda m, name=name: f"{name}: {m}")
        else:
            assert torch.equal(a[name], b[name]), name
    assert torch.equal(cpu.metrics.curve(), gpu.metrics.curve())


@pytest.mark.parametrize("name", list(CONFIGS))
def test_cuda_torch_engine_matches_cpu_numba(world12, demos12, name):
    """Every agent variant, 3000 ticks: the CUDA run is the CPU run."""
    cpu = _make(world12, demos12, CONFIGS[name], "cpu", "numba")
    gpu = _make(world12, demos12, CONFIGS[name], "cuda", "torch")
    assert gpu.values.is_cuda and gpu.engine.name == "torch"
    cpu.run(TICKS)
    gpu.run(TICKS)
    assert_same_run(cpu, gpu)
    assert int(cpu.decisions.min()) > 300 and int(cpu.goals.sum()) > 0


@pytest.mark.parametrize("name", list(CONFIGS))
def test_cuda_checkpoint_resumes_on_the_cpu(world12, demos12, name):
    """A CUDA learner's state_dict loads into a CPU (numba) learner and goes on to the run an
    uninterrupted CPU run makes."""
    straight = _make(world12, demos12, CONFIGS[name], "cpu", "numba")
    straight.run(TICKS)
    gpu = _make(world12, demos12, CONFIGS[name], "cuda", "torch")
    gpu.run(1200)
    resumed = _make(world12, demos12, CONFIGS[name], "cpu", "numba")
    resumed.load_state_dict(gpu.state_dict())
    assert all(not t.is_cuda for t in _state_tensors(resumed))
    resumed.run(TICKS - 1200)
    assert_same_run(straight, resumed)


def _state_tensors(learner: Learner):
    def walk(x):
        if isinstance(x, torch.Tensor):
            yield x
        elif isinstance(x, dict):
            for v in x.values():
                yield from walk(v)
        elif isinstance(x, (list, tuple)):
            for v in x:
                yield from walk(v)
    yield from walk(learner.state_dict())
