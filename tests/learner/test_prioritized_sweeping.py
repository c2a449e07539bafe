"""The batched block priority queue of prioritized sweeping against a naive sort."""

import pytest
import torch

from himit_torch.learner.prioritized_sweeping import BlockPriorityQueue

CPU = torch.device("cpu")


def naive_pop(prio: dict[int, float], n: int, threshold: float) -> list[int]:
    """The slow obvious queue: sort the queued states by priority, take the n best above the
    threshold."""
    ranked = sorted(((p, s) for s, p in prio.items() if p > 0), reverse=True)
    return [s for p, s in ranked[:n] if p > threshold]


def queue_contents(q: BlockPriorityQueue, run: int) -> dict[int, float]:
    p = q.priority[run, : q.num_states]
    return {int(s): float(p[s]) for s in (p > 0).nonzero()[:, 0]}


@pytest.mark.parametrize("block", [1, 3, 8, 64, None])
def test_pop_matches_naive_sort(block):
    gen = torch.Generator().manual_seed(17 + (block or 0))
    B, S = 3, 50
    q = BlockPriorityQueue(B, S, CPU, block=block)
    reference = [dict() for _ in range(B)]
    threshold = 0.2
    for round_ in range(30):
        # push a random batch (repeats of a state in one push included)
        m = int(torch.randint(1, 25, (1,), generator=gen))
        runs = torch.randint(0, B, (m,), generator=gen)
        states = torch.randint(0, S, (m,), generator=gen)
        prios = torch.rand(m, generator=gen, dtype=torch.float64)
        q.push(runs, states, prios)
        for r, s, p in zip(runs.tolist(), states.tolist(), prios.tolist()):
            reference[r][s] = max(reference[r].get(s, 0.0), p)
        # pop from a random subset of runs
        n = int(torch.randint(1, 8, (1,), generator=gen))
        pop_runs = torch.randperm(B, generator=gen)[
            : int(torch.randint(1, B + 1, (1,), generator=gen))
        ]
        popped, valid = q.pop(pop_runs, n, threshold)
        assert popped.shape == valid.shape == (pop_runs.numel(), min(n, q.num_blocks * q.block))
        for i, r in enumerate(pop_runs.tolist()):
            expected = naive_pop(reference[r], n, threshold)
            got = popped[i][valid[i]].tolist()
            assert got == expected, (round_, r, got, expected)
            for s in expected:
                del reference[r][s]
        for r in range(B):
            assert queue_contents(q, r) == pytest.approx(reference[r])
            # the block maxima stay exact
            blocks = q.priority[r].view(q.num_blocks, q.block).amax(1)
            assert torch.equal(q.block_max[r], blocks)


@pytest.mark.parametrize("block", [1, 4, None])
def test_pop_with_tied_priorities_takes_a_top_n(block):
    """With many equal priorities (the learner queues every mentor state at 1.0) a pop returns n
    states whose priorities are the n largest, and leaves none larger behind."""
    gen = torch.Generator().manual_seed(5)
    S = 40
    q = BlockPriorityQueue(1, S, CPU, block=block)
    levels = torch.tensor([0.5, 1.0, 2.0], dtype=torch.float64)
    prios = levels[torch.randint(0, 3, (S,), generator=gen)]
    q.push(torch.zeros(S, dtype=torch.int64), torch.arange(S), prios)
    expected_sorted = sorted(prios.tolist(), reverse=True)
    taken = []
    for n in (3, 7, 1, 12):
        states, valid = q.pop(torch.zeros(1, dtype=torch.int64), n, 0.0)
        got = states[0][valid[0]]
        assert got.unique().numel() == n
        popped = sorted(prios[got].tolist(), reverse=True)
        assert popped == expected_sorted[len(taken) : len(taken) + n]
        left = q.priority[0, :S]
        assert (left[got] == 0).all()
        assert float(left.max()) <= min(popped)
        taken += got.tolist()


def test_push_takes_the_max():
    q = BlockPriorityQueue(1, 10, CPU, block=4)
    run = torch.zeros(1, dtype=torch.int64)
    q.push(run, torch.tensor([3]), torch.tensor([0.5], dtype=torch.float64))
    q.push(run, torch.tensor([3]), torch.tensor([0.3], dtype=torch.float64))
    assert q.priority[0, 3].item() == 0.5
    q.push(run, torch.tensor([3]), torch.tensor([0.9], dtype=torch.float64))
    assert q.priority[0, 3].item() == 0.9
    # several pushes of one state in one call: the largest wins
    q.push(
        torch.zeros(3, dtype=torch.int64),
        torch.tensor([7, 7, 7]),
        torch.tensor([0.2, 0.8, 0.4], dtype=torch.float64),
    )
    assert q.priority[0, 7].item() == 0.8
    states, valid = q.pop(run, 2, 0.0)
    assert states[0].tolist() == [3, 7] and valid.all()


def test_threshold_keeps_low_priorities_queued():
    q = BlockPriorityQueue(1, 20, CPU, block=4)
    run = torch.zeros(1, dtype=torch.int64)
    q.push(
        torch.zeros(4, dtype=torch.int64),
        torch.tensor([1, 5, 9, 13]),
        torch.tensor([0.5, 1e-7, 2.0, 1e-6], dtype=torch.float64),
    )
    states, valid = q.pop(run, 4, threshold=1e-6)
    # 2.0 and 0.5 pass; 1e-6 is not *above* the threshold, 1e-7 neither: both stay queued.
    assert states[0][valid[0]].tolist() == [9, 1]
    assert queue_contents(q, 0) == {5: 1e-7, 13: 1e-6}
    states, valid = q.pop(run, 4, threshold=1e-6)
    assert not valid.any()
    states, valid = q.pop(run, 4, threshold=0.0)
    assert sorted(states[0][valid[0]].tolist()) == [5, 13] and queue_contents(q, 0) == {}


def test_popped_states_are_cleared_and_infinite_priority_first():
    q = BlockPriorityQueue(1, 30, CPU, block=8)
    run = torch.zeros(1, dtype=torch.int64)
    q.push(
        torch.zeros(3, dtype=torch.int64),
        torch.tensor([2, 20, 29]),
        torch.tensor([0.1, float("inf"), 3.0], dtype=torch.float64),
    )
    states, valid = q.pop(run, 1, 0.0)
    assert states.tolist() == [[20]] and valid.all()
    assert q.priority[0, 20].item() == 0.0
    states, valid = q.pop(run, 5, 0.0)
    assert states[0][valid[0]].tolist() == [29, 2]
    assert (q.priority == 0).all() and (q.block_max == 0).all()
    states, valid = q.pop(run, 5, 0.0)
    assert not valid.any()


def test_pop_limit_per_run():
    q = BlockPriorityQueue(2, 16, CPU, block=4)
    runs = torch.tensor([0, 0, 0, 1, 1, 1])
    q.push(
        runs,
        torch.tensor([1, 2, 3, 1, 2, 3]),
        torch.tensor([3.0, 2.0, 1.0, 3.0, 2.0, 1.0], dtype=torch.float64),
    )
    states, valid = q.pop(torch.tensor([0, 1]), 3, 0.0, limit=torch.tensor([1, 3]))
    assert states[0][valid[0]].tolist() == [1]
    assert states[1][valid[1]].tolist() == [1, 2, 3]
    assert queue_contents(q, 0) == {2: 2.0, 3: 1.0} and queue_contents(q, 1) == {}


def test_runs_are_independent():
    """What one run pushes or pops never shows in another run, and a run's pops do not depend on
    the batch it is in."""
    gen = torch.Generator().manual_seed(3)
    S, B = 40, 4
    batched = BlockPriorityQueue(B, S, CPU)
    alone = [BlockPriorityQueue(1, S, CPU) for _ in range(B)]
    for _ in range(20):
        m = 12
        runs = torch.randint(0, B, (m,), generator=gen)
        states = torch.randint(0, S, (m,), generator=gen)
        prios = torch.rand(m, generator=gen, dtype=torch.float64)
        batched.push(runs, states, prios)
        for b in range(B):
            sel = runs == b
            alone[b].push(torch.zeros(int(sel.sum()), dtype=torch.int64), states[sel], prios[sel])
        got, valid = batched.pop(torch.arange(B), 3, 0.05)
        for b in range(B):
            g1, v1 = alone[b].pop(torch.zeros(1, dtype=torch.int64), 3, 0.05)
            assert got[b][valid[b]].tolist() == g1[0][v1[0]].tolist()
    # clearing one run leaves the others
    batched.clear(torch.tensor([1]))
    assert queue_contents(batched, 1) == {}
    for b in (0, 2, 3):
        assert queue_contents(batched, b) == queue_contents(alone[b], 0)


def test_default_block_size_covers_states():
    for S in (1, 7, 64, 65, 6401):
        q = BlockPriorityQueue(2, S, CPU)
        assert q.num_blocks * q.block >= S > (q.num_blocks - 1) * q.block
        q.push(torch.tensor([1]), torch.tensor([S - 1]), torch.tensor([1.0], dtype=torch.float64))
        states, valid = q.pop(torch.tensor([0, 1]), 2, 0.0)
        assert not valid[0].any() and states[1][valid[1]].tolist() == [S - 1]


def test_pop_is_a_prefix_whatever_n_with_ties():
    """Popping n states gives the first n of popping m > n: ties go to the lowest state whatever n
    (torch.topk's tie order depends on n, which made a run's sweep depend on its batch)."""
    torch.manual_seed(0)
    for block in (2, 4, 16):
        priorities = torch.randint(0, 4, (3, 50)).double()  # many ties, some zeros
        results = {}
        for n in (1, 3, 7, 12):
            q = BlockPriorityQueue(3, 50, "cpu", block=block)
            runs, states = torch.arange(3).repeat_interleave(50), torch.arange(50).repeat(3)
            q.push(runs, states, priorities.view(-1))
            results[n] = q.pop(torch.arange(3), n, threshold=0.0)
        for n in (1, 3, 7):
            s_n, v_n = results[n]
            s_m, v_m = results[12]
            assert torch.equal(s_n[v_n], s_m[:, :n][v_m[:, :n]])
        # And the order is (priority desc, state asc), checked against a Python sort.
        s, v = results[12]
        for r in range(3):
            expect = sorted(
                (int(x) for x in range(50) if priorities[r, x] > 0),
                key=lambda x: (-priorities[r, x].item(), x),
            )[:12]
            assert s[r][v[r]].tolist() == expect
