"""The compiled tick loop against the pre-redesign kernel, in one process, on the same arrays.

A side-by-side of two checkouts in separate processes (``bench_ab.py``) moves by ±10 % from one
process to the next on this shared machine, more than the differences it is meant to show. This
one takes both kernels into one process instead: it builds a learner with this checkout, runs
``--warmup`` ticks, catches the arguments of the engine's next ``run_ticks`` call, and from that
snapshot times ``--ticks`` ticks of one run with this checkout's ``run_ticks`` and with the kernel
of ``--base`` (``_kernel._run`` of commit ``c437ddf``, before the redesign: its package is
extracted with ``git archive`` and renamed ``himit_base``), alternating, restoring every array
before each call. Both must end in the same state, bit for bit; it says so. Prints the median
ticks per second of each and their ratio:

    python benchmarks/bench_kernel_inprocess.py [--case 80,10,n,1,imitation] [--reps 21]

``--case``: size, rooms, corner options (``c``) or not (``n``), batch, agent (``mix`` cycles
imitation / options / primitives over the batch, as ``himit bench``). The run timed is run 0 of
the batch. The agents added after the redesign (``bco``, ``pbrs``, ``pbrs_primitives``) are
refused: the base kernel has no cloned policy and no shaping. Only the pre-redesign kernel's argument list is known here, so ``--base``
must be a commit with that kernel (``c437ddf`` or its ancestors back to issue 11).
"""

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
parser.add_argument("--base", default="c437ddf", help="the pre-redesign commit (default c437ddf)")
parser.add_argument("--case", default="80,10,n,1,imitation", help="size,rooms,c|n,batch,agent")
parser.add_argument("--warmup", type=int, default=20000, help="ticks before the snapshot")
parser.add_argument("--ticks", type=int, default=20000, help="ticks timed per call (fewer if the "
                    "edge lists fill first: both kernels stop there)")  # fmt: skip
parser.add_argument("--reps", type=int, default=21, help="timed calls of each kernel")
args = parser.parse_args()


def base_package(commit: str) -> Path:
    """The base commit's package as ``himit_base`` in a temporary folder (kept between runs, so
    that its Numba cache is too)."""
    commit = subprocess.run(  # (the full hash: a branch name would go stale in the cache)
        ["git", "-C", str(ROOT), "rev-parse", "--verify", f"{commit}^{{commit}}"],
        check=True,
        capture_output=True,
        text=True,
    ).stdout.strip()
    where = Path(tempfile.gettempdir()) / f"himit-kernel-base-{commit}"
    if not (where / "himit_base").exists():
        where.mkdir(parents=True, exist_ok=True)
        archive = subprocess.run(
            ["git", "-C", str(ROOT), "archive", commit, "himit_torch"],
            check=True,
            capture_output=True,
        ).stdout
        subprocess.run(["tar", "-x", "-C", str(where)], input=archive, check=True)
        (where / "himit_torch").rename(where / "himit_base")
        for path in (where / "himit_base").rglob("*.py"):
            path.write_text(path.read_text().replace("himit_torch", "himit_base"))
    return where


sys.path.insert(0, str(base_package(args.base)))
import numpy as np  # noqa: E402
import torch  # noqa: E402
from himit_base.engines import _kernel as base_kernel  # noqa: E402

import himit_torch.learner.engines.numba_engine as numba_engine  # noqa: E402
from himit_torch import (  # noqa: E402
    Learner,
    LearnerConfig,
    MultiRooms,
    learner_options,
    mentor_options,
    mentor_policy,
    record_demonstrations,
)
from himit_torch.learner.engines import settings  # noqa: E402

size, rooms, corners, batch, agent = args.case.split(",")
size, rooms, batch, corners = int(size), int(rooms), int(batch), corners == "c"
if agent in ("bco", "pbrs", "pbrs_primitives"):
    sys.exit(f"--case agent {agent!r} came after {args.base}: its kernel cannot run it")
mix = ["imitation", "options", "primitives"]
agents = [mix[b % 3] for b in range(batch)] if agent == "mix" else [agent] * batch
torch.set_num_threads(1)
world = MultiRooms(size=size, rooms=rooms)
demos = record_demonstrations(
    world, mentor_policy(world, mentor_options(world, corners)), 20, seed=0
)
learner = Learner(
    world,
    learner_options(world, corners=corners),
    agents,
    list(range(batch)),
    demonstrations=demos,
    # as himit bench, with no window closing in the timed ticks (the base kernel closed none)
    config=LearnerConfig(plan_every=4, sweep_rounds=1, window=1_000_000),
    engine="numba",
)
caught: dict = {}
run_ticks = numba_engine.run_ticks


def catch(*kernel_args):
    caught.setdefault("args", kernel_args)
    return run_ticks(*kernel_args)


learner.run(args.warmup)
numba_engine.run_ticks = catch
learner.run(1)
numba_engine.run_ticks = run_ticks
(t_end, t_reached, st, world_a, rows, cache, model, mentor, sweep, run, sample, clone, windows,
 scratch) = caught["args"]  # fmt: skip

# the pre-redesign kernel's settings arrays, from the settings tuple
K = base_kernel
cfg_f, cfg_i = np.zeros(K.N_CFG_F), np.zeros(K.N_CFG_I, dtype=np.int64)
for index, value in (
    (K.F_GAMMA, st.gamma),
    (K.F_EPS_DECAY, st.eps_decay),
    (K.F_EPS_MIN, st.eps_min),
    (K.F_THRESHOLD, st.priority_threshold),
    (K.F_V0, st.initial_value),
    (K.F_CONC, st.concentration),
    (K.F_MCONC, st.mentor_concentration),
    (K.F_UNTRIED, st.untried_value),
    (K.F_Z, st.confidence_z),
    (K.F_FADE, st.mentor_fade),
):
    cfg_f[index] = value
for index, value in (
    (K.I_BACKUPS, st.backups),
    (K.I_ROUND, st.round_size),
    (K.I_PLAN_EVERY, st.plan_every),
    (K.I_MAX_STEPS, st.max_option_steps),
    (K.I_UNTRIED_MODE, st.untried_mode),
    (K.I_OVERRIDE, st.mentor_override_after),
    (K.I_MATCH, st.mentor_choice == settings.MATCH),
    (K.I_TIE_FIRST, st.tie_break == settings.TIE_FIRST),
    (K.I_ANY_CONF, st.any_confidence),
    (K.I_ANY_MENTOR, st.any_mentor),
    (K.I_STOCHASTIC, st.stochastic),
    (K.I_START, st.start_state),
    (K.I_EPS_SCHEDULE, st.eps_schedule),
    (K.I_EPS_GOALS, st.eps_goals),
    (K.I_RESAMPLE_EVERY, st.resample_every),
):
    cfg_i[index] = value
r, c, m = rows, cache, model
base_args = (
    run.keys, cfg_f, cfg_i, *world_a,
    r.row_begin, r.row_state, r.row_option, r.row_first_action, r.primitive_rows, r.row_enabled,
    r.use_mentor, r.use_conf,
    c.values, c.q_num, c.q_sec, c.m_num, c.m_sec, c.m_edge_reward,
    m.edge_row, m.edge_succ, m.edge_count, m.edge_disc, m.num_edges, m.row_count, m.row_reward,
    m.state_tries, m.row_head, m.row_next, m.succ_head, m.succ_next,
    *mentor,
    sweep.pending, sweep.heap, sweep.hkey, sweep.hpos, sweep.hsize, sweep.prio,
    *run[1:],
    r.use_sampling, *sample, *scratch,
)  # fmt: skip
new_args = (st, world_a, rows, cache, model, mentor, sweep, run, sample, clone, windows, scratch)

arrays = [a for group in new_args if isinstance(group, tuple) for a in group]
arrays = [a for a in arrays if isinstance(a, np.ndarray)] + [t_reached]
snapshot = [a.copy() for a in arrays]
start = int(t_reached[0])


def timed(kernel: str) -> tuple[float, int, list]:
    """Ticks per second of one call from the snapshot, the ticks done, and the end state."""
    for a, s in zip(arrays, snapshot):
        a[...] = s
    began = time.perf_counter()
    if kernel == "new":
        run_ticks(start + args.ticks, t_reached, *new_args)
    else:
        base_kernel._run(0, start + args.ticks, t_reached, *base_args)
    seconds = time.perf_counter() - began
    done = int(t_reached[0]) - start
    return done / seconds, done, [a.copy() for a in arrays]


timed("new"), timed("base")  # (loaded or compiled before any timing)
rates: dict[str, list[float]] = {"new": [], "base": []}
ends = {}
for i in range(args.reps):
    for kernel in ("new", "base") if i % 2 else ("base", "new"):
        rate, done, ends[kernel] = timed(kernel)
        rates[kernel].append(rate)
same = all(np.array_equal(x, y) for x, y in zip(ends["new"], ends["base"]))
base_rate, new_rate = statistics.median(rates["base"]), statistics.median(rates["new"])
print(
    f"{args.case}, {done} ticks from tick {start}, medians of {args.reps} alternating calls: "
    f"base ({args.base}) {base_rate:,.0f} ticks/s, this checkout {new_rate:,.0f} ticks/s, "
    f"new/base {new_rate / base_rate:.3f}; same end state: {same}"
)
if not same:
    sys.exit("the two kernels ended in different states")
