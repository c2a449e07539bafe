"""What checking a backup's tensor arguments costs a call: the module's hand checks
(:mod:`himit_torch.learner.backups`: kinds, dtypes and shapes compared in Python) against the
same kinds, dtypes and shapes declared with jaxtyping and checked by beartype at each call, both
measured against the bare computation (the function's torch ops, no check), side by side in one
process, alternating.

Three backups at the torch engine's shapes (``[R, n, J]`` option values of ``R`` runs × ``n``
states × ``J`` options, 64 × 16 × 8): ``options_only_backup``, ``augmented_backup`` and
``trusted_augmented_backup`` (the one the engine calls each tick; its nested backups checked
too), and augmented_backup's checks alone (around a function that does nothing). Prints, per function, the median microseconds a call of each way over ``--repeats``
repeats of ``--calls`` calls, and the checks' cost a call (way − bare). Also prints what each
way says to a list where a tensor belongs.

jaxtyping and beartype are not dependencies of the package; the comparison runs where they are
importable (``pip install jaxtyping beartype``, or ``PYTHONPATH=/path/to/them``), else only the
hand checks are measured.

    python benchmarks/bench_arg_checks.py [--calls 2000] [--repeats 7]
"""

import argparse
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
parser.add_argument("--calls", type=int, default=2000)
parser.add_argument("--repeats", type=int, default=7)
args = parser.parse_args()

import torch  # noqa: E402
from torch import Tensor  # noqa: E402

from himit_torch.learner import backups  # noqa: E402

torch.set_num_threads(1)
R, n, J = 64, 16, 8
gen = torch.Generator().manual_seed(0)
option_q = torch.randn(R, n, J, generator=gen, dtype=torch.float64)
available = torch.rand(R, n, J, generator=gen) < 0.7
mentor_term = torch.randn(R, n, generator=gen, dtype=torch.float64)
observed = torch.rand(R, n, generator=gen) < 0.5
NEG_INF = float("-inf")


# ------------------------------------------------------------------ the bare computations
def bare_options_only(option_q, available):
    return torch.where(available, option_q, torch.full_like(option_q, NEG_INF)).max(-1).values


def bare_augmented(own_value, mentor_term, mentor_available):
    return (
        torch.where(mentor_available, torch.maximum(own_value, mentor_term), own_value),
        mentor_available & (mentor_term > own_value),
    )


def bare_trusted(option_q, available, mentor_term, mentor_observed):
    own = bare_options_only(option_q, available)
    return bare_augmented(own, mentor_term, mentor_observed)


def hand_checks_only(own_value, mentor_term, mentor_available):
    """augmented_backup's hand checks (as the module makes them) around no computation."""
    backups._rank("augmented_backup", "own_value", own_value, 0, "[...]")
    backups._same("augmented_backup", "[...] as own_value", own_value.shape,
                  mentor_term=mentor_term, mentor_available=mentor_available)  # fmt: skip
    backups._masks("augmented_backup", mentor_available=mentor_available)


def nothing(own_value, mentor_term, mentor_available):
    """A call that does nothing: the baseline of the checks alone."""


CALLS = {
    "checks alone": ((mentor_term, mentor_term * 0.5, observed), hand_checks_only, nothing),
    "options_only_backup": ((option_q, available), backups.options_only_backup,
                            bare_options_only),
    "augmented_backup": ((mentor_term, mentor_term * 0.5, observed), backups.augmented_backup,
                         bare_augmented),
    "trusted_augmented_backup": ((option_q, available, mentor_term, observed),
                                 backups.trusted_augmented_backup, bare_trusted),
}  # fmt: skip

# ------------------------------------------------------- the same, declared with jaxtyping
try:
    from beartype import beartype
    from jaxtyping import Bool, Float, jaxtyped

    # (the dimension strings as values, not annotations: a linter parses string annotations)
    QJ, MaskJ = Float[Tensor, "*s J"], Bool[Tensor, "*s J"]
    Q, Mask = Float[Tensor, "*s"], Bool[Tensor, "*s"]

    @jaxtyped(typechecker=beartype)
    def jt_options_only(option_q: QJ, available: MaskJ) -> Q:
        return bare_options_only(option_q, available)

    @jaxtyped(typechecker=beartype)
    def jt_augmented(own_value: Q, mentor_term: Q, mentor_available: Mask) -> tuple[Q, Mask]:
        return bare_augmented(own_value, mentor_term, mentor_available)

    @jaxtyped(typechecker=beartype)
    def jt_trusted(
        option_q: QJ, available: MaskJ, mentor_term: Q, mentor_observed: Mask
    ) -> tuple[Q, Mask]:
        own = jt_options_only(option_q, available)
        return jt_augmented(own, mentor_term, mentor_observed)

    @jaxtyped(typechecker=beartype)
    def jt_checks_only(own_value: Q, mentor_term: Q, mentor_available: Mask) -> None:
        """augmented_backup's declarations around no computation: the checks alone."""

    JAXTYPED = {
        "checks alone": jt_checks_only,
        "options_only_backup": jt_options_only,
        "augmented_backup": jt_augmented,
        "trusted_augmented_backup": jt_trusted,
    }
    import jaxtyping

    print(f"jaxtyping {jaxtyping.__version__}, beartype {sys.modules['beartype'].__version__}")
except ImportError:
    JAXTYPED = {}
    print("jaxtyping or beartype not importable: measuring the hand checks only")


def per_call(fn, call_args) -> float:
    """Microseconds a call, over ``--calls`` calls."""
    began = time.perf_counter()
    for _ in range(args.calls):
        fn(*call_args)
    return (time.perf_counter() - began) / args.calls * 1e6


print(f"torch {torch.__version__}, one thread; shapes R×n×J = {R}×{n}×{J}; "
      f"{args.calls} calls × {args.repeats} repeats (medians; a shared, noisy machine)")  # fmt: skip
for name, (call_args, hand, bare) in CALLS.items():
    ways = {"bare": bare, "hand checks": hand}
    if name in JAXTYPED:
        ways["jaxtyping+beartype"] = JAXTYPED[name]
    for fn in ways.values():  # warm up
        per_call(fn, call_args)
    times: dict[str, list[float]] = {w: [] for w in ways}
    for rep in range(args.repeats):
        order = list(ways) if rep % 2 == 0 else list(reversed(ways))
        for way in order:
            times[way].append(per_call(ways[way], call_args))
    med = {w: statistics.median(t) for w, t in times.items()}
    print(f"\n{name}")
    for way, m in med.items():
        extra = "" if way == "bare" else f"   checks {m - med['bare']:+7.2f} µs a call"
        print(f"  {way:20s} {m:8.2f} µs a call{extra}")

print("\nA list where a tensor belongs (augmented_backup's own_value):")
bad = (mentor_term.tolist(), mentor_term, observed)
for way, fn in {"hand checks": backups.augmented_backup, **(
        {"jaxtyping+beartype": JAXTYPED["augmented_backup"]} if JAXTYPED else {})}.items():  # fmt: skip
    try:
        fn(*bad)
    except Exception as err:  # noqa: BLE001 — what each way raises is the point
        text = " ".join(str(err).split())
        print(f"  {way:20s} {type(err).__name__}: {text[:160]}{'…' if len(text) > 160 else ''}")
