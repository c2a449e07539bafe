"""Option builders: primitives, the multirooms doorway and corner options (the learner's
``direct`` and the mentor's wall-following ``walls`` styles), and options that walk to
target states (subgoals)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import torch

from himit_torch.options.bundle import Options, action_dtype
from himit_torch.validation import check_memory
from himit_torch.worlds.multirooms import ACTION_DELTAS, ACTION_NAMES, MultiRooms
from himit_torch.worlds.table_world import world_model

__all__ = [
    "primitive_options",
    "subgoal_options",
    "target_policy",
    "doorway_options",
    "corner_options",
    "learner_options",
    "mentor_options",
    "BYTES_PER_OPTION_STATE",
]


# ------------------------------------------------------------------------------------ builders
def primitive_options(world) -> Options:
    """One option per action: usable in every non-terminal state (and, in MultiRooms, only in
    free cells; in a world with ``affordances [A, S]``, such as the
    :class:`~himit_torch.PuzzleBox`, only where the action can do something), one step, then
    terminate. Works for any world with ``num_states``, ``num_actions`` and ``terminal_mask``;
    names come from ``world.action_names`` if it has them (MultiRooms: ``primitive N`` …
    ``primitive E``)."""
    S, A = world.num_states, world.num_actions
    usable = ~torch.as_tensor(world.terminal_mask, dtype=torch.bool).cpu()
    if hasattr(world, "free_mask"):
        usable = usable & world.free_mask
    initiation = usable[None].repeat(A, 1)
    affordances = getattr(world, "affordances", None)
    if affordances is not None:
        affordances = torch.as_tensor(affordances, dtype=torch.bool).cpu()
        if affordances.shape != (A, S):
            raise ValueError(
                f"{type(world).__name__}.affordances must be [A, S] = [{A}, {S}] bool, got "
                f"{tuple(affordances.shape)}"
            )
        initiation &= affordances
    labels = (
        ACTION_NAMES
        if isinstance(world, MultiRooms)
        else tuple(getattr(world, "action_names", None) or range(A))
    )
    return Options(
        initiation=initiation,
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
    as never arriving). Works on any world with a model (:func:`himit_torch.worlds.table_world.world_model`).

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
    cells, actions = _TargetSearch(world).policy(
        np.asarray(list(region), dtype=np.int64),
        int(target),
        np.asarray(sorted(penalized), dtype=np.int64),
        penalty,
    )
    return dict(zip(cells.tolist(), actions.tolist()))


class _TargetSearch:
    """:func:`~himit_torch.options.target_paths.target_actions` on one world, with the scratch
    arrays it needs made once for all of a world's options."""

    def __init__(self, world: MultiRooms):
        # (imported here: Numba's import, ≈ 0.5 s, stays out of ``import himit_torch``)
        from himit_torch.options.target_paths import target_actions

        self._target_actions = target_actions
        S = world.num_states
        self.successors = np.ascontiguousarray(world._next, dtype=np.int64)
        self.vertical = np.array([dr != 0 for dr, _ in ACTION_DELTAS])
        self.size = world.size
        self.allowed = np.zeros(S, dtype=bool)
        self.cost = np.ones(S)
        self.distance = np.full(S, np.inf)

    def policy(
        self, region: np.ndarray, target: int, penalized: np.ndarray, penalty: float = 10.0
    ) -> tuple[np.ndarray, np.ndarray]:
        """:func:`target_policy` as ``(cells, actions)`` arrays, in the order of ``region``."""
        allowed, cost = self.allowed, self.cost
        allowed[region] = True
        allowed[target] = True
        cost[penalized] = 1.0 + penalty
        actions = self._target_actions(
            self.successors, self.vertical, self.size, allowed, cost, target, region, self.distance
        )
        allowed[region] = False
        allowed[target] = False
        cost[penalized] = 1.0
        found = actions >= 0  # cells cut off from the target inside the region are left out
        return region[found], actions[found]


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
    search = _TargetSearch(world)
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
        in_room = np.array(sorted(set(cells) | set(doors)), dtype=np.int64)
        kept_off = np.array(sorted(penalized), dtype=np.int64)
        rr, rc = divmod(room, world.rooms)
        for label, target in targets_of_room(world, room, cells, doors):
            region = in_room[(in_room != target) & (in_room != goal)]
            if not region.size:
                continue
            states, actions = search.policy(region, target, kept_off[kept_off != target])
            if not states.size:
                continue
            specs.append(
                _SparseOption(
                    f"{kind} room({rr},{rc})->{label}{world.coords(target)}", kind, states, actions
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
    if specs:  # every spec's cells at once, as flat indices into the tables
        sizes = [spec.cells.size for spec in specs]
        rows = np.repeat(np.arange(o, o + len(specs)), sizes)
        flat = torch.from_numpy(rows * S + np.concatenate([spec.cells for spec in specs]))
        initiation.view(-1)[flat] = True
        termination.view(-1)[flat] = 0.0  # runs until it reaches the target or leaves
        actions = np.concatenate([spec.actions for spec in specs])
        policy.view(-1)[flat] = torch.from_numpy(actions).to(policy.dtype)
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
