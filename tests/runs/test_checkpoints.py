"""Checkpoints: the file format (never runs code, checksummed, versioned), two generations with
fallback, refusals of other layouts and batches, failed saves — the issue-13 table row by row."""

import errno
import io
import json
import pickle
import random
import shutil
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pytest
import torch

import himit_torch.runs.checkpoints as ckpt
from himit_torch.cli import main
from himit_torch.learner.learner import Learner
from himit_torch.mentor.policy import mentor_policy, record_demonstrations
from himit_torch.options.builders import learner_options, mentor_options
from himit_torch.runs.checkpoints import (
    BatchShape,
    CheckpointGenerations,
    CheckpointWriteError,
    DamagedCheckpoint,
    IncompatibleCheckpoint,
    NoGoodCheckpoint,
    decode,
    encode,
    read_checkpoint,
    read_header,
    write_checkpoint,
)
from himit_torch.runs.config import EXPERIMENTS
from himit_torch.runs.experiment import run_experiment
from himit_torch.state_checks import DamagedState


@pytest.fixture
def malicious(plants_marker):
    """``malicious(kind, marker)``: the bytes of a file whose unpickling creates ``marker``."""

    def make(kind: str, marker: Path) -> bytes:
        obj = {"learner": plants_marker(marker)}
        if kind == "pickle":
            return pickle.dumps(obj)
        buffer = io.BytesIO()
        torch.save(obj, buffer)
        return buffer.getvalue()

    return make


def test_the_planted_pickles_do_run_code_when_unpickled(tmp_path, malicious):
    """Control for every marker test below: these files are live — plain unpickling (what
    ``torch.load(weights_only=False)`` did) runs their command."""
    a, b = tmp_path / "a", tmp_path / "b"
    pickle.loads(malicious("pickle", a))
    torch.load(io.BytesIO(malicious("torch.save", b)), weights_only=False)
    assert a.exists() and b.exists()


BATCH = BatchShape(("imitation", "primitives"), (0, 0), 64)


def small_payload() -> dict:
    """A payload of every allowed kind, 16 kB (so that a cut to 5000 bytes falls inside it)."""
    return {
        "learner": {
            "values": torch.arange(2000.0, dtype=torch.float64).reshape(2, 1000),
            "t": 7,
            "pending": False,
            "metrics": {"steps": [5, 10], "goals": [torch.tensor([1, 2])]},
            "identity": {"agents": ["a", "b"], "config": {"x": None, "y": 0.5}},
            "pair": (1, "two"),
        },
        "elapsed": 1.5,
    }


def assert_same(a, b):
    if isinstance(a, torch.Tensor):
        assert torch.equal(a, b) and a.dtype == b.dtype
    elif isinstance(a, dict):
        assert a.keys() == b.keys()
        for k in a:
            assert_same(a[k], b[k])
    elif isinstance(a, (list, tuple)):
        assert type(a) is type(b) and len(a) == len(b)
        for x, y in zip(a, b):
            assert_same(x, y)
    else:
        assert a == b and type(a) is type(b)


# ----------------------------------------------------------------------------------- format
def test_round_trip_keeps_the_payload_and_the_header(tmp_path):
    path = tmp_path / "c.pt"
    written = write_checkpoint(path, small_payload(), step=10, batch=BATCH, state_layout_version=3)
    back = read_checkpoint(path, expect_batch=BATCH, expect_layout=3)
    assert_same(back.payload, small_payload())
    assert back.header == written == read_header(path)
    assert (back.header.step, back.header.state_layout_version, back.header.batch) == (10, 3, BATCH)
    assert back.header.format_version == ckpt.FORMAT_VERSION and len(back.header.sha256) == 64
    assert path.read_bytes().startswith(ckpt.MAGIC) and not (tmp_path / "c.pt.tmp").exists()


def test_a_learners_whole_state_loads_weights_only_and_continues_exactly(world8):
    """Today's ``Learner.state_dict()`` (models, queue, metrics, identity) passes the format's
    plain-values check and ``weights_only=True`` as it is, and restores to the same run."""
    options = learner_options(world8)
    demos = record_demonstrations(world8, mentor_policy(world8, mentor_options(world8)), 2, seed=0)

    def make():
        learner = Learner(
            world8, options, ["imitation", "primitives"], [0, 1], demonstrations=demos
        )
        return learner

    a = make()
    a.run(300)
    data = encode({"learner": a.state_dict()}, step=a.views.t, batch=BATCH, state_layout_version=1)
    b = make()
    b.load_state_dict(decode(data).payload["learner"])
    a.run(200)
    b.run(200)
    assert torch.equal(a.views.state_values(), b.views.state_values())
    assert torch.equal(a.metrics.curve(), b.metrics.curve())


def _tensors(obj) -> list[torch.Tensor]:
    if isinstance(obj, torch.Tensor):
        return [obj]
    items = obj.values() if isinstance(obj, dict) else obj if isinstance(obj, list) else []
    return [t for item in items for t in _tensors(item)]


def test_a_learners_live_state_is_written_as_its_copies_byte_for_byte(world8):
    """``state_dict(copy=False)`` (what a checkpoint saves: no copies, views for the edge lists'
    slots in use) gives the file ``state_dict()`` gives, byte for byte — for every owner of
    state: imitation, posterior sampling, behavioural cloning."""
    options = learner_options(world8)
    demos = record_demonstrations(world8, mentor_policy(world8, mentor_options(world8)), 2, seed=0)
    agents = ["imitation", "imitation_psrl", "bco", "primitives"]
    learner = Learner(world8, options, agents, [0, 1, 2, 3], demonstrations=demos)
    learner.run(700)
    copied, live = learner.state_dict(), learner.state_dict(copy=False)
    assert live["model"]["row_count"] is learner.model.row_count  # the learner's own tensors
    live_storages = {t.untyped_storage().data_ptr() for t in _tensors(live)}
    assert (
        not {  # ... and copies of them (the metrics' records are never copied: they are kept)
            t.untyped_storage().data_ptr()
            for k, v in copied.items()
            if k != "metrics"
            for t in _tensors(v)
        }
        & live_storages
    )
    assert any(not t.is_contiguous() for t in _tensors(live))  # (views: the slots in use)
    kwargs = dict(step=learner.views.t, batch=BATCH, state_layout_version=1)
    assert encode({"learner": live}, **kwargs) == encode({"learner": copied}, **kwargs)


@dataclass
class _Stats:
    goals: int


@pytest.mark.parametrize(
    "value, where, what",
    [
        (_Stats(3), "payload.learner.metrics", "_Stats"),
        ([1, {"x": __import__("numpy").int64(2)}], "payload.learner.metrics[1].x", "numpy.int64"),
        ({(1, 2): 3}, "payload.learner.metrics", "key (1, 2)"),
    ],
)
def test_encode_refuses_what_would_need_code_to_load(value, where, what):
    with pytest.raises(TypeError) as err:
        encode({"learner": {"metrics": value}}, step=0, batch=BATCH, state_layout_version=1)
    assert where in str(err.value) and what in str(err.value)


#: kind of damage → how to make it from a good file's bytes (``bad`` makes a live pickle that
#: creates ``marker``), and the words of the reason given.
DAMAGE = {
    "malicious pickle": (
        lambda data, marker, bad: bad("pickle", marker),
        "without the himit_torch",
    ),
    "cut to 5000 bytes": (lambda data, marker, bad: data[:5000], "cut short"),
    "random bytes": (
        lambda data, marker, bad: random.Random(0).randbytes(len(data)),
        "not a himit_torch checkpoint",
    ),
    "empty": (lambda data, marker, bad: b"", "the file is empty"),
    "one byte flipped": (
        lambda data, marker, bad: data[:-100] + bytes([data[-100] ^ 1]) + data[-99:],
        "checksum mismatch",
    ),
    "header cut": (
        lambda data, marker, bad: data[: len(ckpt.MAGIC) + 10],
        "cut short inside its header",
    ),
}


@pytest.mark.parametrize("kind", list(DAMAGE))
def test_damaged_files_are_refused_before_anything_is_unpickled(tmp_path, malicious, kind):
    marker = tmp_path / "marker"
    good = encode(small_payload(), step=10, batch=BATCH, state_layout_version=1)
    make, reason = DAMAGE[kind]
    path = tmp_path / "c.pt"
    path.write_bytes(make(good, marker, malicious))
    with pytest.raises(DamagedCheckpoint) as err:
        read_checkpoint(path)
    assert str(path) in str(err.value) and reason in err.value.reason
    assert not marker.exists()


@pytest.mark.parametrize(
    "kind", [*DAMAGE, "one byte more", "one header byte flipped", "other format", "missing"]
)
def test_the_check_before_promoting_refuses_every_damaged_file(tmp_path, malicious, kind):
    """``_file_is_intact`` (streamed through the checksum, never unpickled: what lets a newest
    file become the previous one) refuses every file that reading refuses as damaged, and of
    another format; and accepts the good file."""
    marker = tmp_path / "marker"
    good = encode(small_payload(), step=10, batch=BATCH, state_layout_version=1)
    path = tmp_path / "c.pt"
    path.write_bytes(good)
    assert ckpt._file_is_intact(path)
    current = f'"format_version":{ckpt.FORMAT_VERSION}'.encode()
    damaged = {
        "one byte more": good + b"\0",
        "one header byte flipped": good.replace(b'"step":10', b'"step":11'),
        "other format": good.replace(current, b'"format_version":9'),
        "missing": None,
    }
    data = damaged[kind] if kind in damaged else DAMAGE[kind][0](good, marker, malicious)
    if data is None:
        path.unlink()
    else:
        path.write_bytes(data)
    assert not ckpt._file_is_intact(path)
    with pytest.raises((DamagedCheckpoint, IncompatibleCheckpoint)):
        read_checkpoint(path)
    assert not marker.exists()


def test_the_check_before_promoting_reads_files_larger_than_its_chunk(tmp_path, monkeypatch):
    """Read a chunk at a time: a file of many chunks passes whole, and fails for one byte
    flipped in any of them, or one missing at the end."""
    monkeypatch.setattr(ckpt, "_CHUNK", 4096)
    good = encode(small_payload(), step=10, batch=BATCH, state_layout_version=1)
    assert len(good) > 3 * 4096
    path = tmp_path / "c.pt"
    path.write_bytes(good)
    assert ckpt._file_is_intact(path)
    for at in (len(good) - 1, len(good) - 5000, len(ckpt.MAGIC) + 500, 9000):
        path.write_bytes(good[:at] + bytes([good[at] ^ 0x10]) + good[at + 1 :])
        assert not ckpt._file_is_intact(path), at
    path.write_bytes(good[:-1])
    assert not ckpt._file_is_intact(path)


def test_a_forged_checksum_still_never_runs_code(tmp_path, malicious):
    """Defence in depth: a file framed like a checkpoint, checksum right, whose payload is a
    malicious torch.save archive — ``weights_only=True`` refuses it unread."""
    marker = tmp_path / "marker"
    body = malicious("torch.save", marker)
    header = ckpt.CheckpointHeader(ckpt.FORMAT_VERSION, 1, 10, BATCH, len(body))
    header = replace(header, sha256=ckpt._checksum(header, body))
    path = tmp_path / "c.pt"
    path.write_bytes(ckpt.MAGIC + header.to_json() + b"\n" + body)
    with pytest.raises(DamagedCheckpoint) as err:
        read_checkpoint(path)
    text = str(err.value)
    assert "refused unread" in text and "system" in text
    assert "weights_only=False" not in text  # torch's advice to do exactly the wrong thing
    assert not marker.exists()


def test_other_format_layout_or_batch_is_refused_naming_both(tmp_path):
    path = tmp_path / "c.pt"
    write_checkpoint(path, small_payload(), step=10, batch=BATCH, state_layout_version=1)
    with pytest.raises(
        IncompatibleCheckpoint, match=r"state layout version 1.*state layout version 2"
    ):
        read_checkpoint(path, expect_layout=2)
    other = BatchShape(("imitation",), (3,), 64)
    with pytest.raises(IncompatibleCheckpoint) as err:
        read_checkpoint(path, expect_batch=other)
    assert BATCH.describe() in str(err.value) and other.describe() in str(err.value)
    current = f'"format_version":{ckpt.FORMAT_VERSION}'.encode()
    future = path.read_bytes().replace(current, b'"format_version":9')
    path.write_bytes(future)
    with pytest.raises(IncompatibleCheckpoint, match="format 9.*reads formats 1, 2"):
        read_checkpoint(path)


# ------------------------------------------------------------------- mostly-zero tensors
def mostly_zeros() -> dict:
    """Tensors a learner's state is made of: big and mostly zero, with the bit patterns a sparse
    store could lose (``-0.0``, NaN with a payload, ±inf), a dense one, and a small one."""
    values = torch.zeros(3, 5000, dtype=torch.float64)
    values[0, 7], values[1, 4999], values[2, 0] = -0.0, float("inf"), -float("inf")
    values[2, 17] = torch.tensor(0x7FF8_0000_0000_1234, dtype=torch.int64).view(torch.float64)
    values[1, 100:200] = torch.linspace(-1, 1, 100, dtype=torch.float64)
    counts = torch.zeros(20_000, dtype=torch.int64)
    counts[::97] = torch.arange(len(counts[::97])) - 50  # negative, zero and positive
    flags = torch.zeros(64, 128, dtype=torch.bool)
    flags[3, 5] = True
    return {
        "values": values,
        "counts": counts,
        "flags": flags,
        "float32": torch.zeros(8192, dtype=torch.float32).index_fill_(0, torch.tensor([9]), -0.0),
        "dense": torch.arange(10_000, dtype=torch.float64),
        "small": torch.zeros(10),
        "nested": [(torch.zeros(5000, dtype=torch.int16),)],
    }


def assert_same_bits(a, b):
    """Equal bit for bit (``torch.equal`` treats -0.0 as 0.0 and NaN as unequal)."""
    if isinstance(a, torch.Tensor):
        assert b.layout == torch.strided and b.is_contiguous()
        assert (a.dtype, a.shape) == (b.dtype, b.shape)
        if a.is_floating_point():
            ints = {2: torch.int16, 4: torch.int32, 8: torch.int64}[a.element_size()]
            a, b = a.view(ints), b.view(ints)
        assert torch.equal(a, b)
    elif isinstance(a, dict):
        assert a.keys() == b.keys()
        for k in a:
            assert_same_bits(a[k], b[k])
    else:
        assert type(a) is type(b) and len(a) == len(b)
        for x, y in zip(a, b):
            assert_same_bits(x, y)


def test_mostly_zero_tensors_are_stored_sparse_and_read_back_bit_for_bit(tmp_path):
    payload = mostly_zeros()
    data = encode(payload, step=1, batch=BATCH, state_layout_version=1)
    back = decode(data)
    assert_same_bits(payload, back.payload)
    # stored sparse: the file is far smaller than its tensors dense
    dense_bytes = sum(
        t.numel() * t.element_size()
        for t in (
            *[v for v in payload.values() if isinstance(v, torch.Tensor)],
            payload["nested"][0][0],
        )
    )
    assert len(data) < dense_bytes - 3 * 5000 * 8  # "values" alone saves most of its 120 kB
    # ... and only those: what it holds as torch.save wrote it
    stored = torch.load(
        io.BytesIO(data[data.index(b"\n", len(ckpt.MAGIC)) + 1 :]), weights_only=True
    )
    layouts = {k: v.layout for k, v in stored.items() if isinstance(v, torch.Tensor)}
    assert layouts == {
        "values": torch.sparse_coo,
        "counts": torch.sparse_coo,
        "flags": torch.sparse_coo,
        "float32": torch.sparse_coo,
        "dense": torch.strided,
        "small": torch.strided,
    }
    assert stored["nested"][0][0].layout == torch.sparse_coo


def test_a_sparse_tensor_in_the_payload_is_refused_by_name():
    payload = {"learner": {"q": torch.zeros(4).to_sparse()}}
    with pytest.raises(TypeError, match=r"payload\.learner\.q: a torch\.sparse_coo tensor"):
        encode(payload, step=1, batch=BATCH, state_layout_version=1)


@pytest.mark.parametrize("index", [-1, 5000])
def test_a_sparse_index_outside_its_tensor_is_a_damaged_file(tmp_path, index):
    """Only an altered file (checksum forged) can hold one; it is refused, not wrapped round."""
    bad = torch.sparse_coo_tensor(
        torch.tensor([[0, index]]), torch.tensor([1.0, 2.0]), (5000,), check_invariants=False
    )
    buffer = io.BytesIO()
    torch.save({"x": bad}, buffer)
    body = buffer.getvalue()
    header = ckpt.CheckpointHeader(ckpt.FORMAT_VERSION, 1, 10, BATCH, len(body))
    header = replace(header, sha256=ckpt._checksum(header, body))
    with pytest.raises(DamagedCheckpoint, match="could not be read"):
        decode(ckpt.MAGIC + header.to_json() + b"\n" + body)


def test_a_format_1_file_still_reads(tmp_path):
    """Format 1 (every tensor dense, before sparse storage) is read as before."""
    payload = mostly_zeros()
    buffer = io.BytesIO()
    torch.save(payload, buffer)
    body = buffer.getvalue()
    header = ckpt.CheckpointHeader(1, 1, 10, BATCH, len(body))
    header = replace(header, sha256=ckpt._checksum(header, body))
    back = decode(ckpt.MAGIC + header.to_json() + b"\n" + body)
    assert back.header.format_version == 1
    assert_same_bits(payload, back.payload)


def _saved(obj) -> bytes:
    buffer = io.BytesIO()
    torch.save(obj, buffer)
    return buffer.getvalue()


def _gathered_by_torch(tensor: torch.Tensor) -> torch.Tensor:
    """What ``_stored`` made of a mostly-zero tensor before NumPy gathered its values (and
    found them in a bool array): the nonzero bit patterns' indices from NumPy, the values
    gathered by torch's indexing."""
    bits = tensor
    if tensor.is_floating_point():
        bits = tensor.view({2: torch.int16, 4: torch.int32, 8: torch.int64}[tensor.element_size()])
    where = np.flatnonzero(bits.numpy().reshape(-1))
    indices = torch.from_numpy(np.stack(np.unravel_index(where, tensor.shape)))
    values = tensor.reshape(-1)[torch.from_numpy(where)]
    return torch.sparse_coo_tensor(
        indices, values, tensor.shape, is_coalesced=True, check_invariants=False
    )


@pytest.mark.parametrize(
    "name", ["values", "counts", "flags", "float32", "nested", "all zeros", "all zeros 2-D"]
)
def test_sparse_storage_gathered_by_numpy_is_what_torch_gathered_byte_for_byte(name):
    """``_stored`` gathers the values with NumPy (faster) and writes what torch's indexing
    gave: the same values and bit patterns, the same torch.save bytes — an empty tensor's
    strides included."""
    tensors = {
        **mostly_zeros(),
        "all zeros": torch.zeros(5000, dtype=torch.float64),
        "all zeros 2-D": torch.zeros(3, 5000, dtype=torch.float64),
    }
    tensor = tensors[name] if name != "nested" else tensors["nested"][0][0]
    stored = ckpt._stored(tensor)
    assert stored.layout == torch.sparse_coo
    assert _saved(stored) == _saved(_gathered_by_torch(tensor))


def test_a_view_is_written_as_its_copy():
    """A view of a larger tensor (what ``state_dict(copy=False)`` gives for the edge lists'
    slots in use) is written as its ``clone()`` is — not with the whole table behind it."""
    table = torch.zeros(4, 9000, dtype=torch.float64)
    table[:, :6000] = torch.arange(24_000, dtype=torch.float64).view(4, 6000)  # dense part
    table[:, 7000] = 1.0  # the rest mostly zeros
    one_run = torch.arange(9000, dtype=torch.int64).view(1, 9000)
    views = {
        "slots in use, stored dense": table[:, :6000],
        "mostly zeros, stored sparse": table[:, 6000:],
        "small": table[:, :10],
        "a row (contiguous, offset)": table[2],
        "one run's slots (contiguous, a larger storage)": one_run[:, :5000],
    }
    kwargs = dict(step=1, batch=BATCH, state_layout_version=1)
    for name, view in views.items():
        as_copy = encode({"x": view.clone()}, **kwargs)
        assert encode({"x": view}, **kwargs) == as_copy, name
        assert len(as_copy) < view.untyped_storage().nbytes(), name  # (not the whole table)
    transposed = torch.arange(5000.0).view(50, 100).T  # its whole storage, strides kept
    assert ckpt._stored(transposed) is transposed


# ------------------------------------------------------------------------------ generations
def save(generations: CheckpointGenerations, step: int):
    return generations.save(
        {"step": step, "x": torch.full((1000,), float(step))},
        step=step,
        batch=BATCH,
        state_layout_version=1,
    )


def test_generations_keep_the_newest_and_the_previous(tmp_path):
    gens = CheckpointGenerations(tmp_path / "world8.pt")
    assert gens.load() is None  # nothing saved yet
    for step in (10, 20, 30):
        save(gens, step)
    assert [read_header(p).step for p in gens.paths] == [30, 20]
    assert gens.previous.name == "world8.prev.pt"
    resumed = gens.load()
    assert resumed.step == 30 and resumed.skipped == []
    assert sorted(p.name for p in tmp_path.iterdir()) == ["world8.prev.pt", "world8.pt"]


def test_a_damaged_newest_falls_back_and_is_never_promoted(tmp_path):
    gens = CheckpointGenerations(tmp_path / "w.pt")
    save(gens, 10)
    save(gens, 20)
    gens.newest.write_bytes(gens.newest.read_bytes()[:5000])
    resumed = gens.load()
    assert resumed.step == 10 and resumed.checkpoint.path == gens.previous
    [skipped] = resumed.skipped
    assert skipped.path == gens.newest and skipped.step == 20 and "cut short" in skipped.reason
    save(gens, 20)  # the resumed run saves again: the damaged file must not become "previous"
    assert [read_header(p).step for p in gens.paths] == [20, 10]
    assert gens.load().step == 20


@pytest.mark.parametrize("refusal", ["state", "file"])
def test_a_newest_whose_restore_is_refused_is_skipped_with_its_reason(tmp_path, refusal):
    """``restore`` refusing the newest generation's state (DamagedState) or the file itself
    (DamagedCheckpoint, a DamagedState too): the previous one is restored, the newest skipped
    with the refusal's own reason and step."""
    gens = CheckpointGenerations(tmp_path / "w.pt")
    save(gens, 10)
    save(gens, 20)
    restored = []

    def restore(found):
        if found.header.step == 20:
            if refusal == "state":
                raise DamagedState("learner.row", "holds a row it never built")
            raise DamagedCheckpoint(found.path, "judged damaged by its reader", 19)
        restored.append(found.header.step)

    resumed = gens.load(restore=restore)
    assert resumed.step == 10 and restored == [10]
    [skipped] = resumed.skipped
    assert skipped.path == gens.newest
    if refusal == "state":
        assert skipped.step == 20
        assert "not one himit_torch writes" in skipped.reason
        assert "holds a row it never built" in skipped.reason
    else:
        assert (skipped.step, skipped.reason) == (19, "judged damaged by its reader")


def test_a_newest_altered_in_place_is_never_promoted(tmp_path):
    """One byte flipped, the size unchanged: only its checksum tells, and it is checked."""
    gens = CheckpointGenerations(tmp_path / "w.pt")
    save(gens, 10)
    save(gens, 20)
    data = gens.newest.read_bytes()
    gens.newest.write_bytes(data[:-100] + bytes([data[-100] ^ 1]) + data[-99:])
    save(gens, 30)
    assert [read_header(p).step for p in gens.paths] == [30, 10]
    assert gens.load().step == 30


def test_no_good_generation_names_each_file(tmp_path):
    gens = CheckpointGenerations(tmp_path / "w.pt")
    save(gens, 10)
    save(gens, 20)
    gens.newest.write_bytes(b"")
    gens.previous.write_bytes(b"junk")
    with pytest.raises(NoGoodCheckpoint) as err:
        gens.load()
    text = str(err.value)
    assert f"{gens.newest}: the file is empty" in text
    assert f"{gens.previous}: not a himit_torch checkpoint" in text


def half_then_disk_full(calls: list):
    """A ``_write_file`` that writes half the bytes, then fails as a full disk does."""

    def write(path: Path, parts: list[bytes]) -> None:
        calls.append(path)
        data = b"".join(parts)
        with path.open("wb") as f:
            f.write(data[: len(data) // 2])
        raise OSError(errno.ENOSPC, "No space left on device")

    return write


def test_a_save_that_fails_half_way_leaves_both_generations_intact(tmp_path, monkeypatch):
    gens = CheckpointGenerations(tmp_path / "w.pt")
    save(gens, 10)
    save(gens, 20)
    before = {p: p.read_bytes() for p in gens.paths}
    calls = []
    monkeypatch.setattr(ckpt, "_write_file", half_then_disk_full(calls))
    with pytest.raises(CheckpointWriteError) as err:
        save(gens, 30)
    assert calls, "the failing writer was not used"
    assert "step 30" in str(err.value) and "No space left on device" in str(err.value)
    assert "untouched" in str(err.value)
    assert {p: p.read_bytes() for p in gens.paths} == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["w.prev.pt", "w.pt"]  # no .tmp left
    monkeypatch.undo()
    assert gens.load().step == 20


# ------------------------------------------------------------------------- through the runner
SIZE = 16


def small_config(**changes):
    """A 16×16 world, 2 runs, 4 windows of 500 steps with a checkpoint after each: seconds. The
    greedy policies are evaluated at 1000 and 2000 steps (a resumed run must restore the first
    evaluation from its checkpoint)."""
    settings = dict(
        sizes=(SIZE,),
        seeds=1,
        steps=2000,
        window=500,
        checkpoint_every=500,
        greedy_every=1000,
        mentor_episodes=3,
        agents=("imitation", "primitives"),
    )
    return replace(EXPERIMENTS["exp2"], **{**settings, **changes})


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> Path:
    """An uninterrupted run (its directory ``…/exp2``): the curves every resumed run must equal."""
    run_dir = tmp_path_factory.mktemp("reference") / "exp2"
    run_experiment(small_config(), run_dir, progress=False)
    return run_dir


def unfinished_copy(reference: Path, tmp_path: Path) -> Path:
    """A copy of the reference run as if it had been killed after its last checkpoint."""
    run_dir = tmp_path / "exp2"
    shutil.copytree(reference, run_dir)
    (run_dir / "worlds" / f"world{SIZE}.json").unlink()
    (run_dir / "results.md").unlink()
    return run_dir


def newest_and_previous(run_dir: Path) -> tuple[Path, Path]:
    return CheckpointGenerations(run_dir / "checkpoints" / f"world{SIZE}.pt").paths


def resume_argv(run_dir: Path) -> list[str]:
    return [
        "run",
        "exp2",
        "--config",
        str(run_dir / "config.json"),
        "--logdir",
        str(run_dir.parent),
        "--quiet",
        "--resume",
    ]


def one_line_error(capsys, argv, status=2) -> str:
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == status
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("himit: error: "), err
    assert "Traceback" not in err
    return err


@pytest.mark.parametrize(
    "kind, redo",
    [
        ("cut to 5000 bytes", "500 steps will be redone"),  # its header still says step 2000
        ("malicious pickle", "the steps after it (up to checkpoint_every=500) will be redone"),
    ],
)
def test_resume_falls_back_to_the_previous_generation_and_ends_with_the_same_curves(
    reference, tmp_path, capsys, malicious, kind, redo
):
    run_dir = unfinished_copy(reference, tmp_path)
    newest, previous = newest_and_previous(run_dir)
    marker = tmp_path / "marker"
    make, reason = DAMAGE[kind]
    newest.write_bytes(make(newest.read_bytes(), marker, malicious))
    assert main(resume_argv(run_dir)) == 0
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    assert err.startswith(f"himit: warning: {newest}: ") and reason in err
    assert f"resuming from {previous.name} at step 1500: {redo}" in err
    assert (run_dir / "curves.csv").read_text() == (reference / "curves.csv").read_text()
    # the final greedy policies under both rules for untried states ("stuck": computed from the
    # final state, not checkpointed) are the uninterrupted run's
    resumed, whole = (
        json.loads((d / "worlds" / f"world{SIZE}.json").read_text()) for d in (run_dir, reference)
    )
    for key in ("greedy_percent_of_optimal", "greedy_percent_of_optimal_stuck"):
        assert json.dumps(resumed[key]) == json.dumps(whole[key]) and len(whole[key]) == 2, key
    assert read_header(newest).step == 2000
    assert not marker.exists()


@pytest.mark.parametrize("kind", ["malicious pickle", "cut to 5000 bytes", "random bytes", "empty"])
def test_no_good_checkpoint_left_is_one_line_naming_the_file_and_exit_2(
    reference, tmp_path, capsys, malicious, kind
):
    run_dir = unfinished_copy(reference, tmp_path)
    marker = tmp_path / "marker"
    make, reason = DAMAGE[kind]
    for path in newest_and_previous(run_dir):
        path.write_bytes(make(path.read_bytes(), marker, malicious))
    err = one_line_error(capsys, resume_argv(run_dir))
    newest, _ = newest_and_previous(run_dir)
    assert f"{newest}: " in err and reason in err and "--force" in err
    assert not marker.exists()


def test_a_checkpoint_of_another_batch_is_refused_naming_both_shapes(reference, tmp_path, capsys):
    run_dir = unfinished_copy(reference, tmp_path)
    newest, _ = newest_and_previous(run_dir)
    other = BatchShape(("imitation", "options", "primitives"), (0, 0, 0), SIZE * SIZE)
    write_checkpoint(
        newest,
        small_payload(),
        step=2000,
        batch=other,
        state_layout_version=Learner.STATE_LAYOUT_VERSION,
    )
    err = one_line_error(capsys, resume_argv(run_dir))
    mine = BatchShape(("imitation", "primitives"), (0, 0), SIZE * SIZE)
    assert other.describe() in err and mine.describe() in err and "--force" in err


def test_another_configuration_is_refused_in_one_line(reference, tmp_path, capsys):
    run_dir = unfinished_copy(reference, tmp_path)
    other = tmp_path / "other.json"
    other.write_text(small_config(seeds=2).to_json())
    argv = resume_argv(run_dir)
    argv[argv.index("--config") + 1] = str(other)
    err = one_line_error(capsys, argv)
    assert str(run_dir / "config.json") in err and "--force" in err


def test_a_checkpoint_of_an_older_state_layout_is_refused_naming_both(
    reference, tmp_path, capsys, monkeypatch
):
    run_dir = unfinished_copy(reference, tmp_path)
    written = read_header(newest_and_previous(run_dir)[0]).state_layout_version
    monkeypatch.setattr(Learner, "STATE_LAYOUT_VERSION", written + 1, raising=False)
    err = one_line_error(capsys, resume_argv(run_dir))
    assert f"state layout version {written}," in err
    assert f"uses state layout version {written + 1}" in err


def test_a_failed_save_stops_the_run_in_one_line_and_keeps_the_last_good_checkpoints(
    reference, tmp_path, capsys, monkeypatch
):
    cfg = tmp_path / "cfg.json"
    cfg.write_text(small_config().to_json())
    run_dir = tmp_path / "exp2"
    newest, previous = newest_and_previous(run_dir)
    writes, snapshot = [], {}
    failing = half_then_disk_full(writes)
    real_write = ckpt._write_file

    def third_save_fails(path: Path, parts: list[bytes]) -> None:
        if len(writes) < 2:
            writes.append(path)
            return real_write(path, parts)
        snapshot.update({p: p.read_bytes() for p in (newest, previous)})
        failing(path, parts)

    monkeypatch.setattr(ckpt, "_write_file", third_save_fails)
    argv = ["run", "exp2", "--config", str(cfg), "--logdir", str(tmp_path), "--quiet"]
    err = one_line_error(capsys, argv, status=1)
    assert f"could not save the checkpoint at step 1500 to {newest}" in err
    assert "No space left on device" in err and "--resume" in err
    assert {p: p.read_bytes() for p in (newest, previous)} == snapshot
    assert [read_header(p).step for p in (newest, previous)] == [1000, 500]
    assert sorted(p.name for p in newest.parent.iterdir()) == ["world16.prev.pt", "world16.pt"]
    monkeypatch.undo()
    assert main(argv + ["--resume"]) == 0
    assert "warning" not in capsys.readouterr().err
    assert (run_dir / "curves.csv").read_text() == (reference / "curves.csv").read_text()
