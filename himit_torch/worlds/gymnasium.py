"""Gymnasium's tabular environments as batched worlds with their true model.

:func:`from_gymnasium` turns any environment whose unwrapped object carries the tabular model
``P[s][a] = [(p, s', r, terminated), …]`` (Gymnasium's toy-text family: Taxi, CliffWalking,
FrozenLake, and your own envs written the same way) into a :class:`~himit_torch.TableWorld`:
a :class:`~himit_torch.DynamicsTable` stepped in batches, the start distribution, the terminal
states and the true model ``P [A, S, S]``, ``R [S, A]`` — so exact value iteration, exact option
models, the mentor and ``himit info`` work on it.

What is kept exactly
    Successors, probabilities and rewards of every ``(s, a)``, in ``P``'s order: the table's
    ``cdf`` is NumPy's cumulative sum of ``P``'s probabilities, and Gymnasium's own ``step``
    takes the first entry whose cumulative probability exceeds its uniform draw — the
    :class:`~himit_torch.DynamicsTable` rule. So the same uniforms give the same transitions
    (tested). Entries of probability 0 are dropped (they are never drawn).

What is not part of the world
    Time limits (``TimeLimit``): the learner runs a continuing stream of episodes. Rendering.
    Anything ``step`` does beyond ``P`` — Taxi's ``fickle_passenger`` is refused for that reason.

Termination
    Gymnasium marks ``terminated`` per transition; the world protocol has ``terminal_mask [S]``,
    the states whose *entry* ends the episode. A state is terminal when some transition into it
    is marked terminated. Then every transition into it from a state the agent can reach (from
    the start distribution, without passing a terminal state) must be marked terminated too; where
    that fails — termination that depends on the transition, not on the state entered — the
    protocol cannot express it and :func:`from_gymnasium` raises ``ValueError`` naming both
    transitions. Pass ``terminal_states=`` to choose the terminal states yourself (Gymnasium's
    flags are then ignored). Transitions *out of* terminal states never happen in an episode;
    the true model makes terminal states absorbing with reward 0.
"""

from __future__ import annotations

import json
from collections import deque
from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np
import torch

from himit_torch.validation import as_float, as_float_array, as_int_array, bool_vector
from himit_torch.worlds.table_world import TableWorld, table_fingerprint
from himit_torch.worlds.tabular import DynamicsTable

__all__ = ["GYM_ACTION_NAMES", "from_gymnasium", "world_from_description"]


#: Action names of Gymnasium's toy-text environments, by the unwrapped class's name.
GYM_ACTION_NAMES = {
    "TaxiEnv": ("south", "north", "east", "west", "pickup", "dropoff"),
    "CliffWalkingEnv": ("up", "right", "down", "left"),
    "FrozenLakeEnv": ("left", "down", "right", "up"),
}


def from_gymnasium(
    env: Any,
    gamma: float = 0.99,
    *,
    start_distribution=None,
    terminal_states: Iterable[int] | torch.Tensor | None = None,
    **kwargs,
) -> TableWorld:
    """A batched world with the true model of a tabular Gymnasium environment.

    Args:
        env: an environment id (``"Taxi-v4"``, ``"FrozenLake-v1"``, …) made with
            ``gymnasium.make(env, **kwargs)``, or an environment object (its ``unwrapped`` is read).
        gamma: the discount (Gymnasium's envs do not carry one), in ``(0, 1]``.
        start_distribution: ``[S]`` probabilities; by default the env's
            ``initial_state_distrib`` (the toy-text envs' own; required for envs without one).
        terminal_states: the terminal states (indices, or an ``[S]`` bool mask) instead of those
            derived from Gymnasium's per-transition ``terminated`` flags (module docstring).
        **kwargs: keyword arguments of ``gymnasium.make`` (only with an id), e.g.
            ``map_name="8x8", is_slippery=True``.

    Returns:
        A :class:`~himit_torch.TableWorld` whose ``describe()`` holds the id, the kwargs, gamma
        and a fingerprint of the model (demonstrations are saved with it), and whose ``env`` is
        the unwrapped environment (e.g. Taxi's ``decode``).

    Raises:
        ValueError: ``gymnasium.make`` fails for the id and keyword arguments (an unknown id, a
            ``module:`` part that does not import, an unknown keyword, a bad ``map_name``: any
            error of Gymnasium's or of the environment's constructor, its type and message
            kept), ``gamma`` is not a real number in ``(0, 1]``, ``terminal_states`` are not
            whole-number states (``None``, ``6.5``, out of range) nor an ``[S]`` bool mask,
            ``start_distribution`` is not real numbers, the environment has no tabular model
            ``P``, spaces that are not ``Discrete``, a malformed ``P``, no start distribution,
            termination that is not per state, or dynamics outside ``P`` (Taxi's
            ``fickle_passenger``).
    """
    gamma = as_float("from_gymnasium: gamma", gamma, 0.0, 1.0, low_open=True)
    if isinstance(env, str):
        env_id = env
        env = _make(env_id, kwargs)
        made_kwargs = {
            k: v
            for k, v in dict(env.spec.kwargs if env.spec else kwargs).items()
            if k != "render_mode"
        }
    else:
        if kwargs:
            raise ValueError(
                f"from_gymnasium: keyword arguments {sorted(kwargs)} are for "
                "gymnasium.make and need an environment id, not an environment object"
            )
        spec = getattr(env, "spec", None)
        env_id = spec.id if spec is not None else None  # type: ignore[assignment]
        made_kwargs = {
            k: v
            for k, v in dict(spec.kwargs if spec is not None else {}).items()
            if k != "render_mode"
        }
    raw = getattr(env, "unwrapped", env)
    label = env_id or type(raw).__name__
    S, A = (
        _discrete_size(raw, "observation_space", label),
        _discrete_size(raw, "action_space", label),
    )
    if getattr(raw, "fickle_passenger", False):
        raise ValueError(
            f"from_gymnasium({label}): fickle_passenger=True changes the destination "
            "inside step(), outside the tabular model P; use fickle_passenger=False"
        )
    P = getattr(raw, "P", None)
    if P is None:
        raise ValueError(
            f"from_gymnasium({label}): the environment has no tabular model: its "
            "unwrapped object needs P[s][a] = [(probability, next state, reward, "
            "terminated), …] for every state s and action a (as Gymnasium's toy-text "
            "environments have)"
        )
    succ, prob, rew, term = _read_model(P, S, A, label)
    cdf = np.cumsum(prob, axis=-1)  # NumPy's order of sums, as in step()
    last = cdf[..., -1]
    if np.abs(last - 1.0).max() > 1e-9:
        s, a = np.unravel_index(np.abs(last - 1.0).argmax(), last.shape)
        raise ValueError(
            f"from_gymnasium({label}): P[{s}][{a}] probabilities sum to "
            f"{float(last[s, a])!r}, not 1"
        )
    cdf[..., -1] = 1.0
    table = DynamicsTable(torch.from_numpy(succ), torch.from_numpy(cdf), torch.from_numpy(rew))

    if start_distribution is None:
        start_distribution = getattr(raw, "initial_state_distrib", None)
        if start_distribution is None:
            raise ValueError(
                f"from_gymnasium({label}): the environment has no "
                "initial_state_distrib; pass start_distribution=[S] probabilities"
            )
        given_start = None
    else:
        start_distribution = as_float_array(
            f"from_gymnasium({label}): start_distribution", start_distribution
        )
        given_start = start_distribution.tolist()
    start = torch.as_tensor(np.asarray(start_distribution, dtype=np.float64))
    if start.shape != (S,):
        raise ValueError(
            f"from_gymnasium({label}): start_distribution of shape "
            f"{tuple(start.shape)}, expected [S] = [{S}]"
        )

    if terminal_states is None:
        terminal = _terminal_from_flags(
            succ, prob, term, start.numpy(), label, GYM_ACTION_NAMES.get(type(raw).__name__)
        )
        given_terminal = None
    else:
        terminal = _mask(terminal_states, S, label)
        given_terminal = terminal.nonzero()[:, 0].tolist()

    fingerprint = table_fingerprint(table, terminal, start)
    if env_id is None:  # identified by the model alone (rebuilding needs the env object)
        description = {
            "kind": "gymnasium",
            "id": None,
            "class": type(raw).__name__,
            "gamma": float(gamma),
            "fingerprint": fingerprint,
        }
    else:
        try:
            json.dumps(made_kwargs)
        except TypeError:
            raise ValueError(
                f"from_gymnasium({label}): keyword arguments {made_kwargs!r} are not "
                "JSON-able, so the world cannot be described for saved "
                "demonstrations"
            ) from None
        description = {
            "kind": "gymnasium",
            "id": env_id,
            "kwargs": made_kwargs,
            "gamma": float(gamma),
        }
        if given_start is not None:
            description["start_distribution"] = given_start
        if given_terminal is not None:
            description["terminal_states"] = given_terminal
        description["fingerprint"] = fingerprint
    world = TableWorld(
        table,
        start,
        terminal,
        gamma=gamma,
        action_names=GYM_ACTION_NAMES.get(type(raw).__name__),
        description=description,
        name=label,
    )
    world.env = raw  # type: ignore[attr-defined]  # extra attributes of a Gymnasium world
    world.gym_id, world.gym_kwargs = env_id, made_kwargs  # type: ignore[attr-defined]
    return world


#: Registered ids whose environment makes another one, named in its kwargs, through the old
#: ``gym`` (Shimmy's compatibility environments): a kwarg of the form ``"module:Id"`` would
#: import that module. Never made from a description.
_MAKES_ANOTHER_ENV = ("GymV21Environment-v0", "GymV26Environment-v0")


def _check_described_id(env_id: Any, kwargs: Any) -> None:
    """Refuse a Gymnasium id and kwargs read from a file (a world description) unless making
    them can import nothing that is not already registered: ``gymnasium.make("module:Id")``
    imports ``module``, so a file naming one could run any importable module's code. The id
    must be a string without ``:`` that Gymnasium's registry holds, the kwargs a dict of
    JSON-able values without ``render_mode`` (never part of a description).

    Raises:
        ValueError: naming the id and what to do instead (pass the world itself).
    """
    import gymnasium

    instead = (
        "a file's Gymnasium id is only used when it is a plain registered id; make the world "
        "yourself (from_gymnasium(...)) and pass it, e.g. Demonstrations.load(path, world=…)"
    )
    if not isinstance(env_id, str):
        raise ValueError(f"the described Gymnasium id {env_id!r} is not a string; {instead}")
    if ":" in env_id:
        raise ValueError(
            f"the described Gymnasium id {env_id!r} names a module to import "
            f"({env_id.split(':')[0]!r}), which is never done for an id read from a file; "
            f"{instead}"
        )
    if env_id not in gymnasium.registry:
        raise ValueError(
            f"the described Gymnasium id {env_id!r} is not registered with Gymnasium here; "
            f"{instead}"
        )
    if env_id in _MAKES_ANOTHER_ENV:
        raise ValueError(
            f"the described Gymnasium id {env_id!r} makes another environment named in its "
            f"kwargs; {instead}"
        )
    if not isinstance(kwargs, dict) or "render_mode" in kwargs:
        raise ValueError(
            f"the described kwargs {kwargs!r} of {env_id!r} are not a description's (a dict "
            f"without render_mode); {instead}"
        )


def world_from_description(description: Mapping) -> TableWorld:
    """Rebuild a :func:`from_gymnasium` world from its ``describe()`` dict (the id and kwargs),
    refusing it if the model's fingerprint differs (another Gymnasium version, say). The
    description comes from a file, so its id must pass ``_check_described_id`` first: it
    never imports a module."""
    if description.get("id") is None:
        raise ValueError(
            "a Gymnasium world made from an environment object without an id cannot "
            "be rebuilt from its description; pass the world itself"
        )
    _check_described_id(description["id"], description.get("kwargs", {}))
    world = from_gymnasium(
        description["id"],
        gamma=description.get("gamma", 0.99),
        start_distribution=description.get("start_distribution"),
        terminal_states=description.get("terminal_states"),
        **description.get("kwargs", {}),
    )
    mine, theirs = world.describe().get("fingerprint"), description.get("fingerprint")
    if theirs is not None and mine != theirs:
        raise ValueError(
            f"{description['id']} with kwargs {description.get('kwargs')} has "
            f"another model here (fingerprint {mine}, described {theirs}): the "
            "installed Gymnasium's environment differs from the one described"
        )
    return world


# ------------------------------------------------------------------------------------ reading P
def _make(env_id: str, kwargs: dict) -> Any:
    """``gymnasium.make(env_id, **kwargs)``; its failures as one ``ValueError`` naming the id and
    the keyword arguments. Whatever the constructor raises (Gymnasium's ``NameNotFound``, an
    ``ImportError`` of a ``module:`` part, a ``TypeError`` for an unknown keyword, FrozenLake's
    ``KeyError`` for an unknown ``map_name``) means that this id with these arguments makes no
    environment: the caller's input, not a fault of this library. The original is chained."""
    import gymnasium

    if not env_id:
        raise ValueError("from_gymnasium: env='' is empty; give an id such as 'FrozenLake-v1'")
    try:
        return gymnasium.make(env_id, **kwargs)
    except OSError:
        raise  # a file the environment reads failed: the machine's fault, not the id's
    except Exception as err:
        given = "".join(f", {k}={v!r}" for k, v in kwargs.items())
        raise ValueError(
            f"from_gymnasium({env_id!r}{given}): gymnasium.make failed with "
            f"{type(err).__name__}: {err}; check the id (gymnasium.pprint_registry() lists "
            "them) and the keyword arguments"
        ) from err


def _discrete_size(raw, name: str, label: str) -> int:
    import gymnasium

    space = getattr(raw, name, None)
    if not isinstance(space, gymnasium.spaces.Discrete):
        raise ValueError(
            f"from_gymnasium({label}): {name} is {space!r}; a tabular world needs "
            "Discrete observation and action spaces"
        )
    if int(space.start) != 0:
        raise ValueError(
            f"from_gymnasium({label}): {name} starts at {int(space.start)}; states "
            "and actions must be numbered from 0"
        )
    return int(space.n)


def _read_model(P, S: int, A: int, label: str):
    """``P[s][a]`` lists → padded arrays ``succ [S, A, K]`` int64, ``prob``, ``rew`` float64,
    ``term`` bool; entries of probability 0 dropped, padding repeats the last entry with
    probability 0 (never drawn)."""
    rows: list[list[list[tuple]]] = []
    K = 1
    for s in range(S):
        try:
            ps = P[s]
            per_action = [list(ps[a]) for a in range(A)]
        except (KeyError, IndexError, TypeError):
            raise ValueError(
                f"from_gymnasium({label}): P[{s}][a] is missing for some action a in "
                f"0…{A - 1}; the model needs every state and action"
            ) from None
        clean = []
        for a, outcomes in enumerate(per_action):
            kept = []
            for entry in outcomes:
                if not (isinstance(entry, (tuple, list)) and len(entry) == 4):
                    raise ValueError(
                        f"from_gymnasium({label}): P[{s}][{a}] holds {entry!r}; "
                        "entries must be (probability, next state, reward, terminated)"
                    )
                p, nxt, r, t = entry
                p, r = float(p), float(r)
                if not (np.isfinite(p) and p >= 0) or not np.isfinite(r):
                    raise ValueError(
                        f"from_gymnasium({label}): P[{s}][{a}] entry {entry!r} has a "
                        "negative or non-finite probability or reward"
                    )
                if not (0 <= int(nxt) < S):
                    raise ValueError(
                        f"from_gymnasium({label}): P[{s}][{a}] leads to state "
                        f"{int(nxt)}, outside 0…{S - 1}"
                    )
                if p > 0:
                    kept.append((p, int(nxt), r, bool(t)))
            if not kept:
                raise ValueError(
                    f"from_gymnasium({label}): P[{s}][{a}] has no outcome of positive probability"
                )
            K = max(K, len(kept))
            clean.append(kept)
        rows.append(clean)
    succ = np.zeros((S, A, K), dtype=np.int64)
    prob = np.zeros((S, A, K), dtype=np.float64)
    rew = np.zeros((S, A, K), dtype=np.float64)
    term = np.zeros((S, A, K), dtype=bool)
    for s, clean in enumerate(rows):
        for a, kept in enumerate(clean):
            padded = kept + [(0.0,) + kept[-1][1:]] * (K - len(kept))
            prob[s, a], succ[s, a], rew[s, a], term[s, a] = zip(*padded)
    return succ, prob, rew, term


def _mask(states, S: int, label: str) -> torch.Tensor:
    """``terminal_states`` as an ``[S]`` mask: given as one (bools), or as state indices, each a
    whole number in ``0…S−1`` (``None`` or ``6.5`` refused, never cast)."""
    where = f"from_gymnasium({label}): terminal_states"
    mask = bool_vector(states)
    if mask is not None and mask.numel():
        if mask.shape != (S,):
            raise ValueError(f"{where}: a mask must be [S] = [{S}] bools, got {mask.numel()}")
        return mask
    mask = torch.zeros(S, dtype=torch.bool)
    mask[torch.from_numpy(as_int_array(where, states, 0, S - 1))] = True
    return mask
    mask = torch.zeros(S, dtype=torch.bool)
    mask[torch.from_numpy(as_int_array(where, states, 0, S - 1))] = True
    return mask


def _terminal_from_flags(succ, prob, term, start, label, action_names) -> torch.Tensor:
    """States entered by some transition marked terminated; checked to be per state on every
    transition the agent can make (see the module docstring)."""
    S = succ.shape[0]
    live = prob > 0
    terminal = np.zeros(S, dtype=bool)
    terminal[succ[live & term]] = True
    # States an episode can visit: from the starts, through non-terminal states.
    seen = np.zeros(S, dtype=bool)
    queue = deque(int(s) for s in np.flatnonzero(start > 0))
    seen[list(queue)] = True
    while queue:
        s = queue.popleft()
        if terminal[s]:
            continue
        for t in np.unique(succ[s][live[s]]):
            if not seen[t]:
                seen[t] = True
                queue.append(int(t))
    src = seen & ~terminal
    bad = live & src[:, None, None] & (term != terminal[succ])
    if bad.any():
        s, a, k = (int(x) for x in np.argwhere(bad)[0])
        t = int(succ[s, a, k])
        other = np.argwhere(live & term & (succ == t))
        name = lambda act: action_names[act] if action_names else str(act)
        if other.size:
            s2, a2, _ = (int(x) for x in other[0])
            why = (
                f"{s2} -({name(a2)})-> {t} ends the episode but {s} -({name(a)})-> {t}, which "
                "the agent can make, does not"
            )
        else:  # unreachable: a terminated flag into a non-terminal state cannot occur
            why = f"{s} -({name(a)})-> {t} is marked terminated inconsistently"
        raise ValueError(
            f"from_gymnasium({label}): Gymnasium marks termination per transition, "
            f"the world protocol per state entered (terminal_mask), and here they "
            f"differ: {why}. Pass terminal_states=… to choose the terminal states "
            "yourself"
        )
    return torch.from_numpy(terminal)
