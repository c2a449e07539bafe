"""Fingerprints of the learner's state after fixed runs: a check that a change kept behaviour.

A refactoring that must leave every curve bit-identical is checked by hashing what the learner
learned — its ``Learner.state_dict()`` (models, values, queue, run state, posterior draws) and,
apart, its curves (the metrics) — after a few fixed runs that between them exercise every code
path of both engines: both engines, options and primitives, the mentor term and its variants
(confidence test, fading, matching, override), posterior sampling, the ε schedules, exact option
models, stochastic start states. Run it before and after the change (with the same Python and
library versions) and compare the lines:

    python benchmarks/state_fingerprint.py [--only NAME ...] > before.txt
    ... change ...
    python benchmarks/state_fingerprint.py > after.txt && diff before.txt after.txt

**A new setting** (docs/extending.md) must change nothing at its default: the runs use every
setting they do not name at its default, and the record of the configuration (the state's
``identity.config`` and ``config_schema``, which gain the new field and perhaps a schema version)
is left out of the hashes, so the lines stay the same unless the default changed what is learned.
A change that adds a piece of state (a new array in a model) changes ``state=`` but must leave
``curves=`` as it was.

Only the public API is used, so the script runs on any layout of the package.
"""

import argparse
import hashlib
import sys
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import himit_torch as ht  # noqa: E402


def _feed(h, value) -> None:
    """Hash ``value`` (nested dicts, lists, tensors, plain values) in a fixed order."""
    if isinstance(value, dict):
        for k in sorted(value, key=str):
            h.update(repr(k).encode())
            _feed(h, value[k])
    elif isinstance(value, (list, tuple)):
        h.update(f"[{len(value)}".encode())
        for v in value:
            _feed(h, v)
    elif isinstance(value, torch.Tensor):
        t = value.detach().cpu()
        if t.is_sparse:
            t = t.to_dense()
        h.update(f"{t.dtype}{tuple(t.shape)}".encode())
        h.update(t.contiguous().numpy().tobytes())
    else:
        h.update(repr(value).encode())


def fingerprint(learner) -> str:
    """``state=<hash> curves=<hash>``: the learner's state but the record of its configuration,
    and its curves (the metrics)."""
    state = learner.state_dict()
    state.pop("config_schema", None)  # (a new setting may bump the schema version)
    state["identity"] = {k: v for k, v in state["identity"].items() if k != "config"}
    curves = state.pop("metrics")
    out = []
    for name, part in (("state", state), ("curves", curves)):
        h = hashlib.sha256()
        _feed(h, part)
        out.append(f"{name}={h.hexdigest()[:16]}")
    return " ".join(out)


def _setup(size, rooms, corners, agents, steps, engine="numba", demos=20, **config):
    world = ht.MultiRooms(size=size, rooms=rooms)
    demonstrations = ht.record_demonstrations(
        world, ht.mentor_policy(world, ht.mentor_options(world, corners=corners)), demos, seed=0
    )
    learner = ht.Learner(
        world,
        ht.learner_options(world, corners=corners),
        agents,
        list(range(len(agents))),
        ht.LearnerConfig(**config),
        demonstrations=demonstrations,
        engine=engine,
    )
    learner.run(steps)
    return learner


EXPERIMENT = {"plan_every": 4, "sweep_rounds": 1}
SETUPS = {
    "40x40": lambda: _setup(
        40, 10, False, ["imitation", "options", "primitives"], 60_000, **EXPERIMENT
    ),
    "64x64c-confident": lambda: _setup(
        64,
        8,
        True,
        ["imitation", "options", "primitives", "imitation_confident"],
        60_000,
        **EXPERIMENT,
    ),
    "80x80c": lambda: _setup(
        80, 10, True, ["imitation", "options", "primitives", "imitation_confident"], 100_000
    ),
    "40x40-psrl-fade-goals": lambda: _setup(
        40,
        10,
        False,
        ["imitation_psrl", "options_psrl", "imitation", "imitation_primitives_psrl"],
        30_000,
        mentor_fade=20.0,
        eps_schedule="goals",
        concentration=1.0,
        mentor_concentration=1.0,
        initial_value=0.0,
        window=2500,
    ),
    "40x40-match-override-step-exact": lambda: _setup(
        40,
        10,
        False,
        ["imitation", "imitation_primitives", "options"],
        20_000,
        mentor_choice="match",
        mentor_override_after=5,
        eps_schedule="step",
        tie_break="first",
        option_models="exact",
        untried_value=0.0,
    ),
    "torch-40x40": lambda: _setup(
        40,
        10,
        False,
        ["imitation", "options", "imitation_confident", "imitation_psrl"],
        1_000,
        engine="torch",
        mentor_choice="match",
        mentor_fade=5.0,
        eps_schedule="paper",
        window=500,
    ),
    "torch-24x24-primitives": lambda: _setup(
        24,
        8,
        False,
        ["primitives", "imitation_primitives_confident", "primitives_psrl"],
        1_500,
        engine="torch",
        plan_every=3,
        sweep_rounds=2,
        window=500,
    ),
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--only", nargs="+", choices=sorted(SETUPS), default=sorted(SETUPS))
    args = parser.parse_args()
    for name in args.only:
        print(f"{name} {fingerprint(SETUPS[name]())}", flush=True)


if __name__ == "__main__":
    main()
