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

import heapq
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import torch

from .table_world import world_model
from .validation import as_tuple, check_memory
from .world import ACTION_DELTAS, ACTION_NAMES, MultiRooms

__all__ = [
    "Options",
    "ACTION_DTYPES",
    "action_dtype",
    "primitive_options",
    "doorway_options",
    "corner_options",
    "learner_options",
    "mentor_options",
    "target_policy",
    "subgoal_options",
    "OPTION_KINDS",
]

#: Kinds of option: ``"primitive"`` (one action, then terminate: what the ``primitives`` agents
#: use), ``"doorway"`` and ``"corner"`` (MultiRooms' builders), ``"subgoal"``
#: (:func:`subgoal_options`) and ``"custom"`` for anything else.
OPTION_KINDS = ("primitive", "doorway", "corner", "subgoal", "custom")

#: Integer dtypes a deterministic ``Options.policy`` may have (unsigned ones are left out: torch
#: reads a uint8 index tensor as a mask).
ACTION_DTYPES = (torch.int8, torch.int16, torch.int32, torch.int64)


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
        if not torch.isfinite(beta).all() or (beta < 0).any() or (beta > 1).any():
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
            A = max(p.policy.shape[2] if p.stochastic else int(p.policy.max()) + 1 for p in bundles)
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
        initiation = torch.as_tensor(initiation)
        if initiation.dtype != torch.bool:
            if initiation.is_complex() or not bool(((initiation == 0) | (initiation == 1)).all()):
                raise ValueError(
                    f"Options.from_policy({name!r}): initiation must be [S] bools "
                    "(or 0/1), got other values"
                )
            initiation = initiation.to(torch.bool)  # 0/1 → False/True, the only conversion
        policy = torch.as_tensor(policy)
        if termination is None:
            termination = (
                torch.ones(initiation.shape) if kind == "primitive" else (~initiation).float()
            )
        termination = torch.as_tensor(termination).float()
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
        """A sub-bundle with the options at ``index``."""
        index = torch.as_tensor(index, dtype=torch.int64)
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


# ------------------------------------------------------------------------------------ builders
def primitive_options(world) -> Options:
    """One option per action: usable in every non-terminal state (and, in MultiRooms, only in
    free cells), one step, then terminate. Works for any world with ``num_states``,
    ``num_actions`` and ``terminal_mask``; names come from ``world.action_names`` if it has them
    (MultiRooms: ``primitive N`` … ``primitive E``)."""
    S, A = world.num_states, world.num_actions
    usable = ~torch.as_tensor(world.terminal_mask, dtype=torch.bool).cpu()
    if hasattr(world, "free_mask"):
        usable = usable & world.free_mask
    labels = (
        ACTION_NAMES
        if isinstance(world, MultiRooms)
        else tuple(getattr(world, "action_names", None) or range(A))
    )
    return Options(
        initiation=usable[None].repeat(A, 1),
        termination=torch.ones(A, S),
        policy=torch.arange(A, dtype=action_dtype(A))[:, None].repeat(1, S),
        names=tuple(f"primitive {n}" for n in labels),
        kinds=("primitive",) * A,
    )


def subgoal_options(
    world, targets: dict, actions: Sequence[int] | None = None, gamma: float = 0.999
) -> Options:
    """One option per named target set of states: it heads for its target by the policy of
    fewest expected steps on the world's *true* model (value iteration with a cost of 1 a step,
    discount ``gamma``, the target absorbing at 0 and the world's other terminal states as bad
    as never arriving). Works on any world with a model (:func:`himit_torch.table_world.world_model`).

    Usable in every non-terminal state outside the target from which the target can be reached;
    it terminates on reaching the target (or leaving that set). Built with
    :meth:`Options.from_policy`, kind ``"subgoal"``.

    Args:
        world: the world.
        targets: ``{name: [S] bool mask}``.
        actions: the actions the options may use (default: all), e.g. Taxi's four moves.
        gamma: the discount of the planning problem (close to 1: fewest expected steps).
    """
    P, _ = world_model(world)
    A, S, _ = P.shape
    actions = list(range(A)) if actions is None else [int(a) for a in actions]
    if not actions or min(actions) < 0 or max(actions) >= A:
        raise ValueError(
            f"subgoal_options: actions {actions} must be a non-empty subset of 0…{A - 1}"
        )
    if not targets:
        raise ValueError("subgoal_options: no targets; give {name: [S] bool mask}")
    idx = P.indices().numpy()
    stacked = sp.csr_matrix((P.values().numpy(), (idx[0] * S + idx[1], idx[2])), shape=(A * S, S))
    stacked = sp.vstack([stacked[a * S : (a + 1) * S] for a in actions]).tocsr()
    terminal = torch.as_tensor(world.terminal_mask, dtype=torch.bool).cpu().numpy()
    never = -1.0 / (1.0 - gamma)
    parts = []
    for name, mask in targets.items():
        target = torch.as_tensor(mask, dtype=torch.bool).cpu().numpy()
        if target.shape != (S,) or not target.any():
            raise ValueError(
                f"subgoal_options: target {name!r} must be a non-empty [S] = [{S}] bool mask"
            )
        fixed = target | terminal
        fixed_value = np.where(target, 0.0, never)
        # From below (every state "never arrives"): unreachable states stay exactly there, and
        # in a deterministic world the values are exact after as many sweeps as the longest path.
        V = np.where(fixed, fixed_value, never)
        for _ in range(100_000):
            q = -1.0 + gamma * (stacked @ V).reshape(len(actions), S)
            new = np.where(fixed, fixed_value, q.max(0))
            done = np.abs(new - V).max() < 1e-9
            V = new
            if done:
                break
        best = q.argmax(0)  # ties to the first of ``actions``
        reach = ~fixed & (V > never + 1e-6)
        if not reach.any():
            raise ValueError(f"subgoal_options: target {name!r} cannot be reached from any state")
        policy = torch.from_numpy(np.asarray(actions)[best]).to(torch.int64)
        parts.append(
            Options.from_policy(torch.from_numpy(reach), policy, name=name, kind="subgoal")
        )
    return Options.concat(parts)


def target_policy(
    world: MultiRooms,
    region: Sequence[int],
    target: int,
    penalized: frozenset[int] = frozenset(),
    penalty: float = 10.0,
) -> dict[int, int]:
    """Deterministic policy from every cell of ``region`` to ``target``, staying inside ``region``
    (cells with no path to the target inside it get no entry).

    Entering a cell costs 1, plus ``penalty`` if it is in ``penalized`` (how the wall-following
    style keeps off a room's middle). Among equally cheap moves it takes the one that closes the
    larger of the row/column gaps to the target, so paths run as straight as the grid allows.
    """
    return _target_policy(world._next.tolist(), world.size, region, target, penalized, penalty)


def _target_policy(
    nxt: list[list[int]],
    size: int,
    region: Sequence[int],
    target: int,
    penalized: frozenset[int],
    penalty: float = 10.0,
) -> dict[int, int]:
    """:func:`target_policy` on the world's successor table as lists (``world._next.tolist()``,
    made once for all of a world's options: reading a numpy table one int at a time was most of
    the cost of building them)."""
    allowed = set(region) | {target}
    cost = {c: 1.0 + (penalty if c in penalized else 0.0) for c in allowed}
    dist = {target: 0.0}
    queue = [(0.0, target)]
    while queue:  # Dijkstra backwards from the target; grid moves are symmetric.
        d, u = heapq.heappop(queue)
        if d > dist[u]:
            continue
        nd = d + cost[u]
        for v in nxt[u]:
            if v == u or v not in allowed or v == target:
                continue
            if nd < dist.get(v, np.inf):
                dist[v] = nd
                heapq.heappush(queue, (nd, v))
    tr, tc = divmod(target, size)
    policy = {}
    for s in region:
        r, c = divmod(s, size)
        best = None
        for a, v in enumerate(nxt[s]):
            if v == s or v not in dist:
                continue
            along = abs(tr - r) if ACTION_DELTAS[a][0] else abs(tc - c)  # the gap it closes
            key = (cost[v] + dist[v], -along, a)
            if best is None or key < best[0]:
                best = (key, a)
        if best is not None:  # cells cut off from the target inside the region are left out
            policy[s] = best[1]
    return policy


def _room_perimeter(world: MultiRooms, cells: list[int]) -> set[int]:
    """Room cells with a wall among their 8 neighbours (or on the grid's edge)."""
    wall, N = world._wall, world.size
    out = set()
    for s in cells:
        r, c = world.coords(s)
        for dr in (-1, 0, 1):
            for dc in (-1, 0, 1):
                rr, cc = r + dr, c + dc
                if not (0 <= rr < N and 0 <= cc < N) or wall[rr, cc]:
                    out.add(s)
    return out


@dataclass(frozen=True)
class _SparseOption:
    """One option given by its initiation cells and the action in each (nothing else stored):
    β is 1 outside the cells, 0 inside; the policy 0 outside."""

    name: str
    kind: str
    cells: np.ndarray  # [n] int64 states of the initiation set
    actions: np.ndarray  # [n] int64 action in each


def _room_target_specs(
    world: MultiRooms, targets_of_room, style: str, kind: str
) -> list[_SparseOption]:
    if style not in ("direct", "walls"):
        raise ValueError(
            f"style={style!r}: use 'direct' (shortest path, the learner's) or 'walls' "
            "(along the room's walls, the mentor's)"
        )
    goal = world.goal_state
    nxt = world._next.tolist()
    specs = []
    for room in range(world.num_rooms):
        cells = world.room_cells(room)
        if not cells:
            continue
        doors = world.room_doorways(room)
        penalized = (
            frozenset(set(cells) - _room_perimeter(world, cells))
            if style == "walls"
            else frozenset()
        )
        rr, rc = divmod(room, world.rooms)
        for label, target in targets_of_room(world, room, cells, doors):
            region = sorted((set(cells) | set(doors)) - {target, goal})
            if not region:
                continue
            pol = _target_policy(nxt, world.size, region, target, penalized=penalized - {target})
            if not pol:
                continue
            specs.append(
                _SparseOption(
                    f"{kind} room({rr},{rc})->{label}{world.coords(target)}",
                    kind,
                    np.fromiter(pol.keys(), np.int64, len(pol)),
                    np.fromiter(pol.values(), np.int64, len(pol)),
                )
            )
    return specs


def _assemble(world, dense: Sequence[Options], specs: Sequence[_SparseOption]) -> Options:
    """``dense`` bundles then ``specs``, written once into preallocated ``[O, S]`` tables (what
    ``Options.concat`` of the same options gives, without building each part's tables first)."""
    S, A = world.num_states, world.num_actions
    O = sum(d.num_options for d in dense) + len(specs)
    dtypes = [d.policy.dtype for d in dense] + [action_dtype(A)]
    initiation = torch.zeros(O, S, dtype=torch.bool)
    termination = torch.ones(O, S)
    policy = torch.zeros(O, S, dtype=max(dtypes, key=lambda t: torch.iinfo(t).bits))
    o = 0
    for d in dense:
        n = d.num_options
        initiation[o : o + n], termination[o : o + n], policy[o : o + n] = (
            d.initiation,
            d.termination,
            d.policy,
        )
        o += n
    for spec in specs:
        cells = torch.from_numpy(spec.cells)
        initiation[o, cells] = True
        termination[o, cells] = 0.0  # runs until it reaches the target or leaves
        policy[o, cells] = torch.from_numpy(spec.actions).to(policy.dtype)
        o += 1
    return Options(
        initiation,
        termination,
        policy,
        sum((d.names for d in dense), ()) + tuple(sp.name for sp in specs),
        sum((d.kinds for d in dense), ()) + tuple(sp.kind for sp in specs),
    )


def _doorway_specs(world: MultiRooms, style: str) -> list[_SparseOption]:
    return _room_target_specs(
        world, lambda w, room, cells, doors: [("door", d) for d in doors], style, "doorway"
    )


def _corner_specs(world: MultiRooms, style: str) -> list[_SparseOption]:
    def targets(w, room, cells, doors):
        rows, cols = zip(*(w.coords(s) for s in cells))
        r0, r1, c0, c1 = min(rows), max(rows), min(cols), max(cols)
        out = []
        for r, c, dr, dc, name in (
            (r0, c0, 1, 1, "NW"),
            (r0, c1, 1, -1, "NE"),
            (r1, c0, -1, 1, "SW"),
            (r1, c1, -1, -1, "SE"),
        ):
            out.append((f"corner {name}", r * w.size + c))
            out.append((f"near {name}", (r + dr) * w.size + c + dc))
        return out

    return _room_target_specs(world, targets, style, "corner")


def doorway_options(world: MultiRooms, style: str = "direct") -> Options:
    """One option per (room, doorway of that room).

    Usable in the room's interior cells and its *other* doorways; it terminates at the target
    doorway or when the agent leaves that set (a slip through another doorway, say).

    Args:
        style: ``"direct"`` heads straight for the doorway by a shortest path (the learner's
            options); ``"walls"`` travels along the room's walls, paying a large cost for each
            cell away from them (the mentor's options, as in the paper's Fig. 2).
    """
    return _assemble(world, [], _nonempty(world, _doorway_specs(world, style), "doorway"))


def corner_options(world: MultiRooms, style: str = "direct") -> Options:
    """Eight options per room: to each of its four corner cells, and to the cell diagonally
    inward from each corner (experiment 1's extraneous options — except the one whose corner is
    the goal). Initiation set and termination as for :func:`doorway_options`."""
    return _assemble(world, [], _nonempty(world, _corner_specs(world, style), "corner"))


def _nonempty(world: MultiRooms, specs: list[_SparseOption], kind: str) -> list[_SparseOption]:
    """Refuse an empty bundle of hand-built options, saying why and what to do."""
    if not specs:
        raise ValueError(
            f"{world!r} has no {kind} options (no room has a {kind} target it can "
            f"head for: {'no doorways' if kind == 'doorway' else 'rooms too small'}); "
            f"leave them out (e.g. learner_options(world, doorways=False))"
        )
    return specs


def learner_options(world: MultiRooms, doorways: bool = True, corners: bool = False) -> Options:
    """The learner's set: primitives, ``direct`` doorway options, optionally corner options
    (the tables written once: no per-part tables joined)."""
    _check_options_size(world, doorways, corners)
    specs = (_doorway_specs(world, "direct") if doorways else []) + (
        _corner_specs(world, "direct") if corners else []
    )
    return _assemble(world, [primitive_options(world)], specs)


def mentor_options(world: MultiRooms, corners: bool = False) -> Options:
    """The mentor's set: primitives, ``walls`` doorway options, optionally corner options (the
    tables written once)."""
    _check_options_size(world, True, corners)
    specs = _doorway_specs(world, "walls") + (_corner_specs(world, "walls") if corners else [])
    return _assemble(world, [primitive_options(world)], specs)


#: Bytes per option and state of an :class:`Options` bundle (β float32, policy int8, initiation
#: bool; the builders write the tables once, with no joined copy): what the up-front size check
#: uses.
BYTES_PER_OPTION_STATE = 4 + 1 + 1


def _check_options_size(world: MultiRooms, doorways: bool, corners: bool) -> None:
    """Refuse a bundle whose dense ``[O, S]`` tables would not fit, before building it."""
    O = (
        world.num_actions
        + (2 * len(world.doorway_rooms) if doorways else 0)
        + (8 * world.num_rooms if corners else 0)
    )
    check_memory(
        f"{O:,} options over {world.num_states:,} states (dense [O, S] tables)",
        O * world.num_states * BYTES_PER_OPTION_STATE,
        "use a smaller world, or no corner options",
    )
