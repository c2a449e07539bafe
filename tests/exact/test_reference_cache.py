"""The disk cache of exact option models (``himit_torch.exact.reference_cache``): a hit is the
computation to the bit, a damaged entry is computed again (never used), and an entry of another
world, other options or another setting is never used."""

import numpy as np
import pytest
import torch

import himit_torch.exact.option_models as om
from himit_torch import MultiRooms, learner_options
from himit_torch.exact import reference_cache
from himit_torch.exact.option_models import option_models_and_durations
from tests.exact.helpers import counting_option_models


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """The disk cache on, in a folder of its own, nothing shared in the process yet."""
    folder = tmp_path / "exact"
    monkeypatch.setenv(reference_cache.CACHE_ENV, str(folder))
    reference_cache._BY_CONTENT.clear()
    yield folder
    reference_cache._BY_CONTENT.clear()


def _same(a, b) -> None:
    assert torch.equal(a.row_state, b.row_state) and torch.equal(a.row_option, b.row_option)
    assert torch.equal(a.reward, b.reward) and a.num_options == b.num_options
    for part in ("crow_indices", "col_indices", "values"):
        x, y = getattr(a.transition, part)(), getattr(b.transition, part)()
        assert x.dtype == y.dtype and torch.equal(x, y), part


def _fresh_process() -> None:
    """What another process finds: nothing in this one's memory."""
    reference_cache._BY_CONTENT.clear()
    om._MEMO.clear()


def test_a_hit_equals_a_recomputation_to_the_bit(cache, monkeypatch):
    world = MultiRooms(16, 4)
    expected = om._option_models(
        world, learner_options(world), [(None, None), (1.0, torch.ones(256, 4))]
    )
    calls = counting_option_models(monkeypatch)
    option_models_and_durations(world, learner_options(world))
    assert calls == [2] and len(list(cache.glob("*.npz"))) == 2  # computed, stored
    _fresh_process()
    # another bundle and another world object of the same content: read from disk
    hit = option_models_and_durations(MultiRooms(16, 4), learner_options(MultiRooms(16, 4)))
    assert calls == [2]
    for got, want in zip(hit, expected):
        _same(got, want)
    # in the same process: shared without reading the disk again
    for path in cache.glob("*.npz"):
        path.unlink()
    again = option_models_and_durations(world, learner_options(world))
    assert calls == [2] and all(a is b for a, b in zip(again, hit))


def _damage(path, how: str) -> None:
    data = bytearray(path.read_bytes())
    if how == "flip a byte of the values":
        at = bytes(data).index(b"data.npy")  # (the values' member: its header, then the array)
        data[at + 8 + 128 + 16] ^= 0xFF
        path.write_bytes(bytes(data))
    elif how == "truncated":
        path.write_bytes(bytes(data[: len(data) // 2]))
    elif how == "not an archive":
        path.write_bytes(b"not a cache entry")
    elif how == "another header":
        with np.load(path, allow_pickle=False) as entry:
            arrays = {k: entry[k] for k in entry.files}
        arrays["reward"] = arrays["reward"] + 1.0  # consistent shapes, a wrong digest
        np.savez(path, **arrays)


@pytest.mark.parametrize(
    "how", ["flip a byte of the values", "truncated", "not an archive", "another header"]
)
def test_a_damaged_entry_is_computed_again_never_used(cache, monkeypatch, how):
    world = MultiRooms(12, 2)
    expected = om._option_models(world, learner_options(world), [(None, None)])[0]
    option_models_and_durations(world, learner_options(world))
    entries = sorted(cache.glob("*.npz"))
    assert len(entries) == 2
    for path in entries:
        _damage(path, how)
    _fresh_process()
    calls = counting_option_models(monkeypatch)
    models, _ = option_models_and_durations(world, learner_options(world))
    assert calls == [2]  # both computed again
    _same(models, expected)
    # and stored anew: the next process reads them
    _fresh_process()
    again, _ = option_models_and_durations(world, learner_options(world))
    assert calls == [2]
    _same(again, expected)


def test_another_worlds_options_or_settings_entry_is_never_used(cache, monkeypatch):
    """Worlds of other dynamics (the slip), other rewards, or options of other content get
    other keys; an entry copied under another key's name is refused by its header."""
    world = MultiRooms(12, 2)
    options = learner_options(world)
    compute = om._option_models  # (the computation itself, not counted)
    calls = counting_option_models(monkeypatch)
    mine, _ = option_models_and_durations(world, options)
    others = [
        MultiRooms(12, 2, slip=0.2),
        MultiRooms(12, 2, step_reward=-0.02),
        MultiRooms(12, 2, gamma=0.95),
    ]
    for other in others:
        _fresh_process()
        theirs, _ = option_models_and_durations(other, learner_options(other))
        want = compute(other, learner_options(other), [(None, None)])[0]
        _same(theirs, want)
        assert not torch.equal(theirs.reward, mine.reward)
    # every discounted model computed anew; the last world's durations (γ = 1, unit costs:
    # the same dynamics) are the first world's, read from the cache
    assert calls == [2, 2, 2, 1]
    # other options in the same world: one option's termination changed
    changed = learner_options(world)
    changed.termination[-1] = 1.0  # (a doorway option; a primitive ends everywhere anyway)
    assert reference_cache.options_fingerprint(changed) != reference_cache.options_fingerprint(
        options
    )
    # an entry under another key's name: refused (its header names its own key), removed
    key = reference_cache.models_key(others[0], learner_options(others[0]), 0.99, "world")
    source = cache / f"{reference_cache.models_key(world, options, 0.99, 'world')}.npz"
    (cache / f"{key}.npz").write_bytes(source.read_bytes())
    _fresh_process()
    assert reference_cache.load_models(key, learner_options(others[0]), om._from_arrays) is None
    assert not (cache / f"{key}.npz").exists()


def test_clear_cache_and_off(cache, monkeypatch):
    world = MultiRooms(12, 2)
    option_models_and_durations(world, learner_options(world))
    assert reference_cache.clear_cache() == 2 and not list(cache.glob("*.npz"))
    monkeypatch.setenv(reference_cache.CACHE_ENV, "off")
    assert reference_cache.cache_dir() is None
    _fresh_process()
    option_models_and_durations(world, learner_options(world))
    assert not cache.exists() or not list(cache.glob("*.npz"))


def _plan_entries(folder) -> list:
    """The cache's plan entries (value iterations), by their header."""
    import json

    found = []
    for path in folder.glob("*.npz"):
        with np.load(path, allow_pickle=False) as entry:
            if json.loads(str(entry["header"][()])).get("kind") == "plan":
                found.append(path)
    return found


def _fresh_process_and_plans() -> None:
    _fresh_process()
    reference_cache._PLANS.clear()


def _counting_plans(monkeypatch) -> list[int]:
    """Count the value iterations computed (not read from the cache)."""
    from himit_torch.exact import planning

    calls: list[int] = []
    compute = planning._smdp_value_iteration

    def counted(models, tol, max_iter):
        calls.append(1)
        return compute(models, tol, max_iter)

    monkeypatch.setattr(planning, "_smdp_value_iteration", counted)
    return calls


def test_a_value_iteration_is_kept_by_its_models_content(cache, monkeypatch):
    """The mentor's policy's and the optimum's value iteration: a hit is the computation to the
    bit; another world's or setting's entry is never used; a damaged entry is computed again."""
    from himit_torch.exact.option_models import option_models
    from himit_torch.exact.planning import _smdp_value_iteration, smdp_value_iteration

    reference_cache._PLANS.clear()
    world = MultiRooms(16, 4)
    want = _smdp_value_iteration(option_models(world, learner_options(world)), 1e-10, 100_000)
    calls = _counting_plans(monkeypatch)
    first = smdp_value_iteration(option_models(world, learner_options(world)))
    assert calls == [1] and len(_plan_entries(cache)) == 1
    _fresh_process_and_plans()
    hit = smdp_value_iteration(option_models(MultiRooms(16, 4), learner_options(MultiRooms(16, 4))))
    assert calls == [1]  # read from disk, in a "new process"
    for got in (first, hit):
        assert got.iterations == want.iterations
        for part in ("values", "policy", "q"):
            x, y = getattr(got, part), getattr(want, part)
            assert x.dtype == y.dtype and torch.equal(x, y), part
    hit.values[0] = 123.0  # (a caller's copy: what is kept does not change)
    again = smdp_value_iteration(option_models(world, learner_options(world)))
    assert calls == [1] and torch.equal(again.values, want.values)
    # another tolerance, another world: computed, never the entry above
    smdp_value_iteration(option_models(world, learner_options(world)), tol=1e-6)
    slip = MultiRooms(16, 4, slip=0.2)
    other = smdp_value_iteration(option_models(slip, learner_options(slip)))
    assert calls == [1, 1, 1] and not torch.equal(other.values, want.values)
    # a damaged entry: removed, computed again, the result the computation's
    for path in _plan_entries(cache):
        data = bytearray(path.read_bytes())
        at = bytes(data).index(b"values.npy")
        data[at + 8 + 128 + 8] ^= 0xFF
        path.write_bytes(bytes(data))
    _fresh_process_and_plans()
    redone = smdp_value_iteration(option_models(world, learner_options(world)))
    assert calls == [1, 1, 1, 1] and torch.equal(redone.values, want.values)
    # models made another way (not kept by content) are solved, never looked up
    _fresh_process_and_plans()
    plain = om._option_models(world, learner_options(world), [(None, None)])[0]
    smdp_value_iteration(plain)
    assert calls == [1, 1, 1, 1, 1]
