"""Options (Sutton, Precup & Singh 1999) as a bundle of tensors shared by a batch of runs.

An option is ``(I, β, π)``: where it may start (initiation set ``I``), the probability ``β(s')``
that it terminates on arriving in ``s'``, and the policy it follows meanwhile. ``O`` options over
``S`` states are stored as

* ``initiation``  ``[O, S]`` bool,
* ``termination`` ``[O, S]`` float32 (β),
* ``policy``      ``[O, S]`` integer action index (any signed integer dtype; the builders here
  use the smallest that holds the actions, ``int8`` for up to 127 actions), or ``[O, S, A]``
  float32 action probabilities.

Memory: on 120×120 with corner options (2,644 options × 14,400 states) these tables are what
dominates a process, so the builders write each table once into a preallocated tensor (no lists
of per-option rows, no stacking or joining copies) and keep the policy in ``int8``: 0.23 GB for a
bundle instead of 0.5 GB plus ~1.5 GB of temporaries. Code that indexes with an action taken from
``policy`` should convert it with ``.long()`` (torch indexes only with int64/int32).

Every option also terminates when it reaches a terminal state of the world (the goal): the run
loop and the exact option models add that, it need not be written into β.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import torch

from himit_torch.validation import as_int_array, as_tuple

__all__ = ["OPTION_KINDS", "ACTION_DTYPES", "action_dtype", "Options"]


#: Kinds of option: ``"primitive"`` (one action, then terminate: what the ``primitives`` agents
#: use), ``"doorway"`` and ``"corner"`` (MultiRooms' builders), ``"subgoal"``
#: (:func:`subgoal_options`) and ``"custom"`` for anything else.
OPTION_KINDS = ("primitive", "doorway", "corner", "subgoal", "custom")

#: Integer dtypes a deterministic ``Options.policy`` may have (unsigned ones are left out: torch
#: reads a uint8 index tensor as a mask).
ACTION_DTYPES = (torch.int8, torch.int16, torch.int32, torch.int64)


def _as_tensor(where: str, value) -> torch.Tensor:
    """A tensor, array or (nested) list as a tensor; ``None``, strings and ragged lists are
    refused by name."""
    if value is None or isinstance(value, (str, bytes)):
        raise ValueError(f"{where} must be a tensor, array or list, got {value!r}")
    try:
        return torch.as_tensor(value)
    except (TypeError, ValueError, RuntimeError) as err:
        raise ValueError(f"{where} must be a tensor, array or list of numbers ({err})") from None


def action_dtype(num_actions: int) -> torch.dtype:
    """The smallest of :data:`ACTION_DTYPES` that holds action indices ``0 … num_actions - 1``."""
    for dtype in ACTION_DTYPES:
        if num_actions - 1 <= torch.iinfo(dtype).max:
            return dtype
    raise ValueError(f"num_actions={num_actions} does not fit an int64 action index")


@dataclass(frozen=True)
class Options:
    """``O`` options over ``S`` states. See the module docstring for the tensors' meaning."""

    initiation: torch.Tensor
    termination: torch.Tensor
    policy: torch.Tensor
    names: tuple[str, ...]
    kinds: tuple[str, ...]

    def __post_init__(self):
        for name in ("initiation", "termination", "policy"):
            if not isinstance(getattr(self, name), torch.Tensor):
                raise ValueError(
                    f"Options.{name} must be a torch.Tensor, got "
                    f"{type(getattr(self, name)).__name__}"
                )
        for name in ("names", "kinds"):  # a list is stored as a tuple; a bare string is refused
            value = as_tuple(f"Options.{name}", getattr(self, name))
            if not all(isinstance(v, str) for v in value):
                raise ValueError(f"Options.{name} must hold strings, got {list(value)[:5]}")
            object.__setattr__(self, name, value)
        init, beta, pol = self.initiation, self.termination, self.policy
        if init.dim() != 2 or init.dtype != torch.bool:
            raise ValueError(
                f"Options.initiation must be a [O, S] bool tensor, got "
                f"{tuple(init.shape)} {init.dtype}"
            )
        O, S = init.shape
        if O == 0:
            raise ValueError("Options needs at least one option (got O = 0)")
        if beta.shape != (O, S) or not beta.is_floating_point():
            raise ValueError(
                f"Options.termination must be a [O, S] = [{O}, {S}] float tensor, got "
                f"{tuple(beta.shape)} {beta.dtype}"
            )
        # One pass and no [O, S] temporaries: NaN fails both comparisons, ±inf one of them
        # (isfinite, < 0 and > 1 apart took 0.5 s on 120×120's 38 M entries, aminmax 0.01 s).
        low, high = torch.aminmax(beta) if beta.numel() else (0.0, 0.0)
        if not (0 <= float(low) and float(high) <= 1):
            raise ValueError("Options.termination (β) must hold probabilities in [0, 1]")
        if pol.dim() == 2:
            if pol.shape != (O, S) or pol.dtype not in ACTION_DTYPES:
                raise ValueError(
                    f"Options.policy must be [O, S] = [{O}, {S}] integer actions "
                    f"(int8, int16, int32 or int64) or [O, S, A] probabilities, got "
                    f"{tuple(pol.shape)} {pol.dtype}"
                )
            if pol.numel() and (pol.min() < 0):
                raise ValueError("Options.policy holds a negative action index")
        elif pol.dim() == 3:
            if pol.shape[:2] != (O, S) or not pol.is_floating_point():
                raise ValueError(
                    f"Options.policy probabilities must be [O, S, A] = [{O}, {S}, A] "
                    f"float, got {tuple(pol.shape)} {pol.dtype}"
                )
            sums = pol.sum(-1)[init]
            if (pol < 0).any() or not torch.allclose(sums, torch.ones_like(sums), atol=1e-5):
                raise ValueError(
                    "Options.policy probabilities must be ≥ 0 and sum to 1 over "
                    "actions in every initiation state"
                )
        else:
            raise ValueError(f"Options.policy must have 2 or 3 dimensions, got {pol.dim()}")
        if len(self.names) != O or len(self.kinds) != O:
            raise ValueError(
                f"Options needs one name and one kind per option: {O} options, "
                f"{len(self.names)} names, {len(self.kinds)} kinds"
            )
        bad = sorted(set(self.kinds) - set(OPTION_KINDS))
        if bad:
            raise ValueError(f"unknown option kinds {bad}; use one of {OPTION_KINDS}")
        empty = torch.nonzero(~init.any(1)).flatten().tolist()
        if empty:
            raise ValueError(
                f"options {[self.names[o] for o in empty[:5]]} have an empty initiation "
                "set: an option that can start nowhere can never be used; drop it"
            )

    # ------------------------------------------------------------------------------ queries
    @property
    def num_options(self) -> int:
        return self.initiation.shape[0]

    @property
    def num_states(self) -> int:
        return self.initiation.shape[1]

    @property
    def is_primitive(self) -> torch.Tensor:
        """``[O]`` bool, True for one-step primitive options."""
        return torch.tensor([k == "primitive" for k in self.kinds], dtype=torch.bool)

    @property
    def stochastic(self) -> bool:
        return self.policy.dim() == 3

    def action_probabilities(self, num_actions: int) -> torch.Tensor:
        """``[O, S, A]`` float32 policy, one-hot for deterministic policies."""
        if self.stochastic:
            return self.policy.float()
        return torch.nn.functional.one_hot(self.policy.long(), num_actions).float()

    def __len__(self) -> int:
        return self.num_options

    def __add__(self, other: Options) -> Options:
        return Options.concat(self, other)

    @staticmethod
    def concat(*parts: Options | Sequence[Options]) -> Options:
        """Options from several bundles, in order (policies made stochastic if any one is):
        ``Options.concat(a, b)`` or ``Options.concat([a, b])``."""
        items: tuple = (
            tuple(parts[0]) if len(parts) == 1 and isinstance(parts[0], (list, tuple)) else parts
        )
        if not items:
            raise ValueError("Options.concat needs at least one bundle")
        wrong = [type(p).__name__ for p in items if not isinstance(p, Options)]
        if wrong:
            raise ValueError(
                f"Options.concat joins Options bundles, got {wrong}; pass bundles as "
                "separate arguments or as one list"
            )
        bundles: list[Options] = list(items)
        if len({p.num_states for p in bundles}) != 1:
            raise ValueError(
                f"cannot join options over different state counts {[p.num_states for p in bundles]}"
            )
        if any(p.stochastic for p in bundles):
            counts = sorted({p.policy.shape[2] for p in bundles if p.stochastic})
            A = counts[-1]
            largest = max((int(p.policy.max()) for p in bundles if not p.stochastic), default=-1)
            if len(counts) > 1 or largest >= A:
                raise ValueError(
                    f"Options.concat: the bundles' policies are over different action counts "
                    f"(probabilities over {counts} actions"
                    + (f", integer actions up to {largest}" if largest >= 0 else "")
                    + "); join options of one world, whose policies share its actions"
                )
            policy = torch.cat([p.action_probabilities(A) for p in bundles])
        else:
            policy = torch.cat([p.policy for p in bundles])
        return Options(
            initiation=torch.cat([p.initiation for p in bundles]),
            termination=torch.cat([p.termination for p in bundles]),
            policy=policy,
            names=sum((p.names for p in bundles), ()),
            kinds=sum((p.kinds for p in bundles), ()),
        )

    @staticmethod
    def from_policy(
        initiation: torch.Tensor,
        policy: torch.Tensor,
        termination: torch.Tensor | None = None,
        name: str = "custom",
        kind: str = "custom",
    ) -> Options:
        """One option from any tabular policy.

        Args:
            initiation: ``[S]`` bool where it may start.
            policy: ``[S]`` int64 actions or ``[S, A]`` probabilities.
            termination: ``[S]`` β; by default 1 outside the initiation set, 0 inside (the option
                runs until it leaves the set) — for ``kind="primitive"``, 1 everywhere.
            name: the option's name.
            kind: one of :data:`OPTION_KINDS`. ``"primitive"`` marks a one-step option — the
                ``primitives`` agents use only those — so it must terminate everywhere
                (``β = 1``) and take one fixed action in every initiation state.
        """
        if kind not in OPTION_KINDS:
            raise ValueError(
                f"Options.from_policy: kind={kind!r} is unknown; use one of {OPTION_KINDS}"
            )
        initiation = _as_tensor(f"Options.from_policy({name!r}): initiation", initiation)
        if initiation.dtype != torch.bool:
            if initiation.is_complex() or not bool(((initiation == 0) | (initiation == 1)).all()):
                raise ValueError(
                    f"Options.from_policy({name!r}): initiation must be [S] bools "
                    "(or 0/1), got other values"
                )
            initiation = initiation.to(torch.bool)  # 0/1 → False/True, the only conversion
        policy = _as_tensor(f"Options.from_policy({name!r}): policy", policy)
        if termination is None:
            termination = (
                torch.ones(initiation.shape) if kind == "primitive" else (~initiation).float()
            )
        termination = _as_tensor(f"Options.from_policy({name!r}): termination", termination)
        if termination.dtype == torch.bool or not (
            termination.is_floating_point() or termination.dtype in ACTION_DTYPES
        ):
            raise ValueError(
                f"Options.from_policy({name!r}): termination must be [S] probabilities, got "
                f"dtype {termination.dtype}"
            )
        termination = termination.float()
        if kind == "primitive":
            if (
                initiation.dim() != 1
                or termination.shape != initiation.shape
                or not bool((termination == 1).all())
            ):
                raise ValueError(
                    f"Options.from_policy({name!r}, kind='primitive'): a primitive "
                    "option executes one action and terminates, so its termination "
                    "must be 1 in every state"
                )
            if (
                policy.is_floating_point()
                or policy.dim() != 1
                or policy[initiation].unique().numel() > 1
            ):
                raise ValueError(
                    f"Options.from_policy({name!r}, kind='primitive'): a primitive "
                    "option takes one fixed action: give an [S] int64 policy with the "
                    "same action in every initiation state"
                )
        return Options(
            initiation=initiation[None],
            termination=termination[None],
            policy=policy[None],
            names=(name,),
            kinds=(kind,),
        )

    def select(self, index: Sequence[int] | torch.Tensor) -> Options:
        """A sub-bundle with the options at ``index``: whole numbers in ``0…O−1`` (a list, array
        or tensor; a bool mask is refused, use ``mask.nonzero()[:, 0]``)."""
        index = torch.from_numpy(
            as_int_array("Options.select: index", index, 0, self.num_options - 1)
        )
        return Options(
            self.initiation[index],
            self.termination[index],
            self.policy[index],
            tuple(self.names[i] for i in index.tolist()),
            tuple(self.kinds[i] for i in index.tolist()),
        )

    def __repr__(self) -> str:
        counts = {k: self.kinds.count(k) for k in OPTION_KINDS if k in self.kinds}
        return f"Options(O={self.num_options}, S={self.num_states}, {counts})"
