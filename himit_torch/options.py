"""Options (Sutton, Precup & Singh 1999) as a bundle of tensors shared by a batch of runs.

An option is ``(I, β, π)``: where it may start (initiation set ``I``), the probability ``β(s')``
that it terminates on arriving in ``s'``, and the policy it follows meanwhile. ``O`` options over
``S`` states are stored as

* ``initiation``  ``[O, S]`` bool,
* ``termination`` ``[O, S]`` float32 (β),
* ``policy``      ``[O, S]`` int64 action index, or ``[O, S, A]`` float32 action probabilities.

Every option also terminates when it reaches a terminal state of the world (the goal): the run
loop and the exact option models add that, it need not be written into β.
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass
from typing import Sequence

import numpy as np
import torch

from .world import ACTION_DELTAS, MultiRooms

__all__ = ["Options", "primitive_options", "doorway_options", "corner_options",
           "learner_options", "mentor_options", "target_policy"]

#: Kinds of option the builders make; ``"custom"`` for user-built ones.
OPTION_KINDS = ("primitive", "doorway", "corner", "custom")


@dataclass(frozen=True)
class Options:
    """``O`` options over ``S`` states. See the module docstring for the tensors' meaning."""

    initiation: torch.Tensor
    termination: torch.Tensor
    policy: torch.Tensor
    names: tuple[str, ...]
    kinds: tuple[str, ...]

    def __post_init__(self):
        init, beta, pol = self.initiation, self.termination, self.policy
        if init.dim() != 2 or init.dtype != torch.bool:
            raise ValueError(f"Options.initiation must be a [O, S] bool tensor, got "
                             f"{tuple(init.shape)} {init.dtype}")
        O, S = init.shape
        if O == 0:
            raise ValueError("Options needs at least one option (got O = 0)")
        if beta.shape != (O, S) or not beta.is_floating_point():
            raise ValueError(f"Options.termination must be a [O, S] = [{O}, {S}] float tensor, got "
                             f"{tuple(beta.shape)} {beta.dtype}")
        if not torch.isfinite(beta).all() or (beta < 0).any() or (beta > 1).any():
            raise ValueError("Options.termination (β) must hold probabilities in [0, 1]")
        if pol.dim() == 2:
            if pol.shape != (O, S) or pol.dtype != torch.int64:
                raise ValueError(f"Options.policy must be [O, S] = [{O}, {S}] int64 actions or "
                                 f"[O, S, A] probabilities, got {tuple(pol.shape)} {pol.dtype}")
            if pol.numel() and (pol.min() < 0):
                raise ValueError("Options.policy holds a negative action index")
        elif pol.dim() == 3:
            if pol.shape[:2] != (O, S) or not pol.is_floating_point():
                raise ValueError(f"Options.policy probabilities must be [O, S, A] = [{O}, {S}, A] "
                                 f"float, got {tuple(pol.shape)} {pol.dtype}")
            sums = pol.sum(-1)[init]
            if (pol < 0).any() or not torch.allclose(sums, torch.ones_like(sums), atol=1e-5):
                raise ValueError("Options.policy probabilities must be ≥ 0 and sum to 1 over "
                                 "actions in every initiation state")
        else:
            raise ValueError(f"Options.policy must have 2 or 3 dimensions, got {pol.dim()}")
        if len(self.names) != O or len(self.kinds) != O:
            raise ValueError(f"Options needs one name and one kind per option: {O} options, "
                             f"{len(self.names)} names, {len(self.kinds)} kinds")
        bad = sorted(set(self.kinds) - set(OPTION_KINDS))
        if bad:
            raise ValueError(f"unknown option kinds {bad}; use one of {OPTION_KINDS}")
        empty = torch.nonzero(~init.any(1)).flatten().tolist()
        if empty:
            raise ValueError(f"options {[self.names[o] for o in empty[:5]]} have an empty initiation "
                             "set: an option that can start nowhere can never be used; drop it")

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
        return torch.nn.functional.one_hot(self.policy, num_actions).float()

    def __len__(self) -> int:
        return self.num_options

    def __add__(self, other: "Options") -> "Options":
        return Options.concat(self, other)

    @staticmethod
    def concat(*parts: "Options") -> "Options":
        """Options from several bundles, in order (policies made stochastic if any one is)."""
        if not parts:
            raise ValueError("Options.concat needs at least one bundle")
        if len({p.num_states for p in parts}) != 1:
            raise ValueError(f"cannot join options over different state counts "
                             f"{[p.num_states for p in parts]}")
        if any(p.stochastic for p in parts):
            A = max(p.policy.shape[2] if p.stochastic else int(p.policy.max()) + 1 for p in parts)
            policy = torch.cat([p.action_probabilities(A) for p in parts])
        else:
            policy = torch.cat([p.policy for p in parts])
        return Options(initiation=torch.cat([p.initiation for p in parts]),
                       termination=torch.cat([p.termination for p in parts]),
                       policy=policy, names=sum((p.names for p in parts), ()),
                       kinds=sum((p.kinds for p in parts), ()))

    @staticmethod
    def from_policy(initiation: torch.Tensor, policy: torch.Tensor,
                    termination: torch.Tensor | None = None, name: str = "custom") -> "Options":
        """One option from any tabular policy.

        Args:
            initiation: ``[S]`` bool where it may start.
            policy: ``[S]`` int64 actions or ``[S, A]`` probabilities.
            termination: ``[S]`` β; by default 1 outside the initiation set, 0 inside (the option
                runs until it leaves the set).
        """
        initiation = torch.as_tensor(initiation, dtype=torch.bool)
        if termination is None:
            termination = (~initiation).float()
        return Options(initiation=initiation[None], termination=torch.as_tensor(termination).float()[None],
                       policy=torch.as_tensor(policy)[None], names=(name,), kinds=("custom",))

    def select(self, index: Sequence[int] | torch.Tensor) -> "Options":
        """A sub-bundle with the options at ``index``."""
        index = torch.as_tensor(index, dtype=torch.int64)
        return Options(self.initiation[index], self.termination[index], self.policy[index],
                       tuple(self.names[i] for i in index.tolist()),
                       tuple(self.kinds[i] for i in index.tolist()))

    def __repr__(self) -> str:
        counts = {k: self.kinds.count(k) for k in OPTION_KINDS if k in self.kinds}
        return f"Options(O={self.num_options}, S={self.num_states}, {counts})"


# ------------------------------------------------------------------------------------ builders
def primitive_options(world: MultiRooms) -> Options:
    """One option per action: usable in every free non-goal cell, one step, then terminate."""
    S, A = world.num_states, world.num_actions
    usable = world.free_mask & ~world.terminal_mask
    return Options(initiation=usable[None].repeat(A, 1),
                   termination=torch.ones(A, S),
                   policy=torch.arange(A)[:, None].repeat(1, S),
                   names=tuple(f"primitive {n}" for n in "NSWE"), kinds=("primitive",) * A)


def target_policy(world: MultiRooms, region: Sequence[int], target: int,
                  penalized: frozenset[int] = frozenset(), penalty: float = 10.0) -> dict[int, int]:
    """Deterministic policy from every cell of ``region`` to ``target``, staying inside ``region``
    (cells with no path to the target inside it get no entry).

    Entering a cell costs 1, plus ``penalty`` if it is in ``penalized`` (how the wall-following
    style keeps off a room's middle). Among equally cheap moves it takes the one that closes the
    larger of the row/column gaps to the target, so paths run as straight as the grid allows.
    """
    allowed = set(region) | {target}
    nxt = world._next
    cost = {c: 1.0 + (penalty if c in penalized else 0.0) for c in allowed}
    dist = {target: 0.0}
    queue = [(0.0, target)]
    while queue:  # Dijkstra backwards from the target; grid moves are symmetric.
        d, u = heapq.heappop(queue)
        if d > dist[u]:
            continue
        for v in nxt[u]:
            v = int(v)
            if v == u or v not in allowed or v == target:
                continue
            nd = d + cost[u]
            if nd < dist.get(v, np.inf):
                dist[v] = nd
                heapq.heappush(queue, (nd, v))
    tr, tc = world.coords(target)
    policy = {}
    for s in region:
        r, c = world.coords(s)
        best = None
        for a, (dr, dc) in enumerate(ACTION_DELTAS):
            v = int(nxt[s, a])
            if v == s or v not in dist:
                continue
            along = abs(tr - r) if dr else abs(tc - c)          # the gap this move closes
            key = (cost[v] + dist[v], -along, a)
            if best is None or key < best[0]:
                best = (key, a)
        if best is not None:      # cells cut off from the target inside the region are left out
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


def _room_target_options(world: MultiRooms, targets_of_room, style: str, kind: str) -> Options:
    if style not in ("direct", "walls"):
        raise ValueError(f"style={style!r}: use 'direct' (shortest path, the learner's) or 'walls' "
                         "(along the room's walls, the mentor's)")
    S = world.num_states
    goal = world.goal_state
    inits, betas, policies, names = [], [], [], []
    for room in range(world.num_rooms):
        cells = world.room_cells(room)
        if not cells:
            continue
        doors = world.room_doorways(room)
        penalized = frozenset(set(cells) - _room_perimeter(world, cells)) if style == "walls" \
            else frozenset()
        rr, rc = divmod(room, world.rooms)
        for label, target in targets_of_room(world, room, cells, doors):
            region = sorted((set(cells) | set(doors)) - {target, goal})
            if not region:
                continue
            pol = target_policy(world, region, target, penalized=penalized - {target})
            if not pol:
                continue
            init = torch.zeros(S, dtype=torch.bool)
            init[list(pol)] = True
            policy = torch.zeros(S, dtype=torch.int64)
            policy[list(pol)] = torch.tensor(list(pol.values()))
            inits.append(init)
            betas.append((~init).float())      # runs until it reaches the target or leaves
            policies.append(policy)
            names.append(f"{kind} room({rr},{rc})->{label}{world.coords(target)}")
    return Options(torch.stack(inits), torch.stack(betas), torch.stack(policies),
                   tuple(names), (kind,) * len(names))


def doorway_options(world: MultiRooms, style: str = "direct") -> Options:
    """One option per (room, doorway of that room).

    Usable in the room's interior cells and its *other* doorways; it terminates at the target
    doorway or when the agent leaves that set (a slip through another doorway, say).

    Args:
        style: ``"direct"`` heads straight for the doorway by a shortest path (the learner's
            options); ``"walls"`` travels along the room's walls, paying a large cost for each
            cell away from them (the mentor's options, as in the paper's Fig. 2).
    """
    return _room_target_options(world, lambda w, room, cells, doors: [("door", d) for d in doors],
                                style, "doorway")


def corner_options(world: MultiRooms, style: str = "direct") -> Options:
    """Eight options per room: to each of its four corner cells, and to the cell diagonally
    inward from each corner (experiment 1's extraneous options — except the one whose corner is
    the goal). Initiation set and termination as for :func:`doorway_options`."""

    def targets(w, room, cells, doors):
        rows, cols = zip(*(w.coords(s) for s in cells))
        r0, r1, c0, c1 = min(rows), max(rows), min(cols), max(cols)
        out = []
        for r, c, dr, dc, name in ((r0, c0, 1, 1, "NW"), (r0, c1, 1, -1, "NE"),
                                   (r1, c0, -1, 1, "SW"), (r1, c1, -1, -1, "SE")):
            out.append((f"corner {name}", r * w.size + c))
            out.append((f"near {name}", (r + dr) * w.size + c + dc))
        return out

    return _room_target_options(world, targets, style, "corner")


def learner_options(world: MultiRooms, doorways: bool = True, corners: bool = False) -> Options:
    """The learner's set: primitives, ``direct`` doorway options, optionally corner options."""
    parts = [primitive_options(world)]
    if doorways:
        parts.append(doorway_options(world, "direct"))
    if corners:
        parts.append(corner_options(world, "direct"))
    return Options.concat(*parts)


def mentor_options(world: MultiRooms, corners: bool = False) -> Options:
    """The mentor's set: primitives, ``walls`` doorway options, optionally corner options."""
    parts = [primitive_options(world), doorway_options(world, "walls")]
    if corners:
        parts.append(corner_options(world, "walls"))
    return Options.concat(*parts)
