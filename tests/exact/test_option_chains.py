"""The compiled option chain against the obvious computation: a breadth-first search over Python
sets and the kernel's entries walked one by one, split by the definitions of each part."""

import numpy as np
import pytest
import scipy.sparse as sp
import torch

from himit_torch.exact.option_chains import option_chain
from himit_torch.options.builders import corner_options, doorway_options, primitive_options
from himit_torch.options.bundle import Options
from himit_torch.worlds.multirooms import MultiRooms
from himit_torch.worlds.table_world import world_model


def _csr(world):
    P, _ = world_model(world)
    A, S, _ = P.shape
    idx = P.indices().numpy()
    stack = sp.csr_matrix((P.values().numpy(), (idx[0] * S + idx[1], idx[2])), shape=(A * S, S))
    stack.eliminate_zeros()
    return stack.indptr.astype(np.int64), stack.indices.astype(np.int64), stack.data


def _entries(csr, S, actions, probabilities, s):
    """The kernel's entries from ``s``: ``(next state, probability)`` by action, then successor."""
    indptr, indices, data = csr
    if probabilities is None:
        weights = [(int(actions[s]), None)]
    else:
        weights = [(a, p) for a, p in enumerate(probabilities[s]) if p > 0]
    for a, p in weights:
        row = a * S + s
        for k in range(indptr[row], indptr[row + 1]):
            yield int(indices[k]), data[k] if p is None else data[k] * p


def _obvious(csr, terminal, beta, actions, probabilities, start):
    S = terminal.size

    def stop(t):
        return 1.0 if terminal[t] else beta[t]

    found: set[int] = set()
    frontier = [int(s) for s in start]
    while frontier:
        new = []
        for s in frontier:
            for t, p in _entries(csr, S, actions, probabilities, s):
                if p > 0 and 1.0 - stop(t) > 0 and t not in found:
                    found.add(t)
                    new.append(t)
        frontier = new
    continuing = sorted(found)
    local = {s: i for i, s in enumerate(continuing)}
    parts: dict[str, list] = {k: [] for k in ("hit", "cc", "exit", "jc")}
    for i, s in enumerate([int(s) for s in start] + continuing):
        for t, p in _entries(csr, S, actions, probabilities, s):
            go_on, ends = p * (1.0 - stop(t)), p * stop(t)
            if i < start.size:
                if ends > 0:
                    parts["hit"].append((i, t, ends))
                if go_on > 0:
                    parts["jc"].append((i, local[t], go_on))
            else:
                if go_on > 0:
                    parts["cc"].append((i - start.size, local[t], go_on))
                if ends > 0:
                    parts["exit"].append((i - start.size, t, ends))
    return continuing, parts


def _check(world, options):
    csr, S = _csr(world), world.num_states
    terminal = world.terminal_mask.numpy()
    scratch = np.full(S, -1, dtype=np.int64)
    for o in range(options.num_options):
        start = np.flatnonzero(options.initiation[o].numpy())
        beta = options.termination[o].double().numpy()
        if options.stochastic:
            probabilities = options.policy[o].double().numpy()
            actions = np.zeros(0, np.int64)
        else:
            probabilities, actions = None, options.policy[o].numpy().astype(np.int64)
        if probabilities is None:
            chain_policy = (actions[:, None], np.ones((S, 1)))
        else:
            A = probabilities.shape[1]
            chain_policy = (np.tile(np.arange(A, dtype=np.int64), (S, 1)), probabilities)
        chain = option_chain(*csr, terminal, beta, *chain_policy, start, scratch)
        continuing, parts = _obvious(csr, terminal, beta, actions, probabilities, start)
        assert chain.continuing.tolist() == continuing, options.names[o]
        hit = list(zip(chain.hit_row.tolist(), chain.hit_state.tolist(), chain.hit_value))
        assert hit == parts["hit"]
        cc = list(zip(chain.cc_row.tolist(), chain.cc_col.tolist(), chain.cc_value))
        assert cc == parts["cc"]
        exits = chain.exits[chain.exit_col].tolist()
        assert list(zip(chain.exit_row.tolist(), exits, chain.exit_value)) == parts["exit"]
        assert chain.exits.tolist() == sorted({t for _, t, _ in parts["exit"]})
        j = chain.j_state[chain.jc_row].tolist()
        assert list(zip(j, chain.jc_col.tolist(), chain.jc_value)) == parts["jc"]
        assert chain.j_state.tolist() == sorted({i for i, _, _ in parts["jc"]})
        assert (scratch == -1).all()  # left as it came


@pytest.mark.parametrize("slip", [0.0, 0.3])
def test_deterministic_options_equal_the_obvious_chain(slip):
    world = MultiRooms(size=12, rooms=3, slip=slip)
    options = Options.concat(primitive_options(world), doorway_options(world))
    options = Options.concat(options, corner_options(world, style="walls"))
    _check(world, options)


def test_stochastic_options_with_partial_termination_equal_the_obvious_chain():
    """Random walks that stop with β < 1 inside a room (one holds the goal, a terminal state the
    walk may go on from only by stopping) and always outside it."""
    world = MultiRooms(size=8, rooms=2, slip=0.2)
    generator = torch.Generator().manual_seed(3)
    bundles = []
    for room in range(world.num_rooms):
        cells = torch.zeros(world.num_states, dtype=torch.bool)
        cells[world.room_cells(room)] = True
        policy = torch.rand(world.num_states, world.num_actions, generator=generator)
        policy[:, 1] = 0.0  # an action never taken
        policy /= policy.sum(-1, keepdim=True)
        beta = torch.where(cells, 0.25, 1.0)
        bundles.append(Options.from_policy(cells, policy, termination=beta, name=f"walk {room}"))
    options = Options.concat(bundles)
    assert options.stochastic and world.goal_state in world.room_cells(world.num_rooms - 1)
    _check(world, options)
