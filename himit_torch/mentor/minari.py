"""Demonstrations to and from Minari datasets (Farama's format for offline RL and imitation).

:func:`demonstrations_from_minari` reads a dataset's episodes' *observations* as states of a
world — datasets whose observations are the world's discrete states: a toy-text task, or a
MiniGrid task recorded through the library's state encoding
(:meth:`~himit_torch.MiniGridWorld.state_of`) — and ignores the actions: the demonstrations are
state-only, as everywhere in the library. :func:`demonstrations_to_minari` writes a local
dataset: the mentor's policy run in the real environment (MiniGrid's or Gymnasium's own
``step``), each step's observation the world's state, written by Minari's own writer
(``minari.create_dataset_from_buffers``; Minari's ``DataCollector`` wrapper would record the
same episodes but needs JAX only to append to its buffers).

What Minari's loader can execute, and the guard
    A Minari dataset is a folder: ``metadata.json`` and the data (HDF5 or Arrow). Minari reads
    the observation and action spaces from the metadata; where one is missing it makes the
    environment named in the metadata's ``env_spec`` with ``gymnasium.make`` — whose
    ``entry_point`` (and each wrapper's) is ``"module:attr"``: it imports that module and calls
    it, any code the file names. ``MinariDataset.recover_environment()`` does the same on
    purpose, and ``minari.load_dataset(..., download=True)`` reaches the network. So this module
    reads ``metadata.json`` itself first (plain JSON) and refuses a dataset without both spaces
    serialized, or in a storage format other than Minari's own (HDF5, Arrow, Parquet), before
    Minari opens it; looks a dataset id up in the local folder only (never downloads); never
    recovers an environment; and refuses observation spaces that are not ``Discrete`` before any
    data is read (image spaces would be JPEG-decoded by Pillow). HDF5 and Arrow reading runs no
    stored code (no pickles).

Refused (``ValueError``, naming what is wrong and what would be right): observations that are
not the world's states (images, dicts, a ``Discrete`` space of another size, values out of
range, steps the world cannot make), a damaged or missing dataset, a dataset recorded in another
world.
"""

from __future__ import annotations

import json
import os
import re
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import torch

from himit_torch.mentor.demonstrations import Demonstrations
from himit_torch.mentor.policy import MentorPolicy
from himit_torch.validation import COUNT_MAX, as_int
from himit_torch.worlds.table_world import describe_world

__all__ = ["demonstrations_from_minari", "demonstrations_to_minari"]

#: Storage formats Minari itself writes (their readers run no stored code).
_FORMATS = ("hdf5", "arrow", "parquet")
#: What a dataset's description starts with when this library wrote it (then the world's).
_WORLD_PREFIX = "himit_torch world: "
_DATASET_ID = re.compile(r"^([A-Za-z0-9_.-]+/)*[A-Za-z0-9_.-]+$")


def _import_minari():
    os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
    try:
        import minari
    except ImportError:
        raise ValueError(
            "Minari is not installed: pip install 'himit_torch[minigrid]' (or 'minari[hdf5]')"
        ) from None
    return minari


def _data_path(dataset: str | os.PathLike) -> Path:
    """The folder holding ``metadata.json``: a path given (the dataset's folder or its ``data``
    folder), or a dataset id looked up in Minari's local folder (``MINARI_DATASETS_PATH``)."""
    path = Path(dataset)
    for candidate in (path, path / "data"):
        if (candidate / "metadata.json").is_file():
            return candidate
    if isinstance(dataset, str) and _DATASET_ID.match(dataset) and ".." not in dataset:
        from minari.storage.datasets_root_dir import get_dataset_path

        try:
            local = Path(get_dataset_path(dataset)) / "data"
        except Exception as err:
            raise ValueError(f"Minari dataset id {dataset!r}: {err}") from None
        if (local / "metadata.json").is_file():
            return local
        raise ValueError(
            f"no local Minari dataset {dataset!r} (looked in {local}); datasets are never "
            "downloaded here: download it yourself (minari download ID) or give its folder"
        )
    raise ValueError(
        f"no Minari dataset at {str(dataset)!r}: give a dataset folder holding "
        "data/metadata.json, or a local dataset id such as 'himit/doorkey-v0'"
    )


def _checked_metadata(path: Path) -> dict:
    """``metadata.json`` read as plain JSON and checked so that Minari's loader makes no
    environment (module docstring)."""
    where = f"Minari dataset {path}"
    try:
        metadata = json.loads((path / "metadata.json").read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
        raise ValueError(f"{where}: metadata.json is damaged ({err})") from None
    if not isinstance(metadata, dict):
        raise ValueError(f"{where}: metadata.json holds {type(metadata).__name__}, not an object")
    for key in ("observation_space", "action_space"):
        if not isinstance(metadata.get(key), str):
            raise ValueError(
                f"{where}: metadata.json has no serialized {key}; Minari would then make the "
                "environment named in its env_spec (importing the module it names) to learn "
                "it, which is never done for a dataset here. Write the dataset with both "
                "spaces (as Minari does by default)"
            )
    if metadata.get("data_format") not in _FORMATS:
        raise ValueError(
            f"{where}: data_format {metadata.get('data_format')!r} is not one of Minari's "
            f"own {list(_FORMATS)}"
        )
    return metadata


def _discrete_size(metadata: dict, where: str) -> int:
    from minari.serialization import deserialize_space

    try:
        space = deserialize_space(metadata["observation_space"])
    except Exception as err:
        raise ValueError(f"{where}: the observation space is damaged ({err})") from None
    import gymnasium

    if not isinstance(space, gymnasium.spaces.Discrete) or int(space.start) != 0:
        raise ValueError(
            f"{where}: observations of {space}; demonstrations need the world's discrete "
            "states (Discrete(S) from 0): a toy-text task, or MiniGrid recorded through the "
            "world's state encoding (demonstrations_to_minari), not images or dicts"
        )
    return int(space.n)


def demonstrations_from_minari(dataset: Any, world, *, episodes: int | None = None):
    """A Minari dataset's episodes as state-only :class:`~himit_torch.Demonstrations` of
    ``world`` (each episode's observations, the actions ignored).

    Args:
        dataset: a dataset folder (or its ``data`` folder), a local dataset id (looked up in
            ``MINARI_DATASETS_PATH``; never downloaded), or a ``minari.MinariDataset`` you
            loaded yourself.
        world: the world whose states the observations are (its ``num_states`` must be the
            observation space's ``n``).
        episodes: read only the first this many episodes (default all).

    Raises:
        ValueError: the dataset cannot be found, is damaged, names an environment to make, or
            its observations are not this world's states (module docstring); or it was written
            by :func:`demonstrations_to_minari` in another world.
    """
    _import_minari()
    from minari import MinariDataset
    from minari.dataset.minari_storage import MinariStorage

    if isinstance(dataset, MinariDataset):
        where = f"Minari dataset {dataset.spec.dataset_id!r}"
        metadata = dataset.storage.metadata
        n = _discrete_size({"observation_space": _serialized(dataset.observation_space)}, where)
        data = dataset
    else:
        if not isinstance(dataset, (str, os.PathLike)):
            raise TypeError(
                "dataset must be a folder, a local dataset id or a MinariDataset, got "
                f"{type(dataset).__name__}"
            )
        path = _data_path(dataset)
        where = f"Minari dataset {path}"
        metadata = _checked_metadata(path)
        n = _discrete_size(metadata, where)
        try:
            data = MinariDataset(MinariStorage.read(path))
        except Exception as err:
            raise ValueError(
                f"{where}: Minari cannot read it ({type(err).__name__}: {err})"
            ) from None
    if n != int(world.num_states):
        raise ValueError(
            f"{where}: observations are Discrete({n}) but the world has {world.num_states} "
            "states: a dataset of another world (or another layout, seed or size)"
        )
    _check_recorded_world(metadata, world, where)
    total = int(data.total_episodes)
    count = total if episodes is None else as_int("episodes", episodes, 1, total)
    out = []
    try:
        for i, episode in enumerate(data.iterate_episodes(range(count))):
            obs = np.asarray(episode.observations)
            if obs.ndim != 1 or obs.dtype.kind not in "iu":
                raise ValueError(
                    f"{where}: episode {i}'s observations are {obs.dtype} of shape {obs.shape}, "
                    "not one whole-number state per step"
                )
            out.append(torch.from_numpy(obs.astype(np.int64)))
    except ValueError:
        raise
    except Exception as err:  # h5py's and pyarrow's errors on a damaged file
        raise ValueError(f"{where}: its data is damaged ({type(err).__name__}: {err})") from None
    if not out:
        raise ValueError(f"{where}: no episodes")
    return Demonstrations(out, world, source=where)


def _serialized(space) -> str:
    from minari.serialization import serialize_space

    try:
        return str(serialize_space(space))
    except Exception as err:
        raise ValueError(
            f"the dataset's observation space {space} is not Discrete ({err})"
        ) from None


def _check_recorded_world(metadata: dict, world, where: str) -> None:
    """A dataset this library wrote names its world: it must be ``world``."""
    description = metadata.get("description")
    if not isinstance(description, str) or not description.startswith(_WORLD_PREFIX):
        return
    try:
        recorded = json.loads(description[len(_WORLD_PREFIX) :])
    except json.JSONDecodeError as err:
        raise ValueError(f"{where}: its world description is damaged ({err})") from None
    mine = describe_world(world)
    if recorded != mine:
        differ = sorted(k for k in set(recorded) | set(mine) if recorded.get(k) != mine.get(k))
        raise ValueError(
            f"{where}: recorded in another world (fields that differ: {differ}); read it into "
            "the world it was recorded in"
        )


def demonstrations_to_minari(
    world,
    mentor: MentorPolicy,
    dataset_id: str,
    episodes: int = 10,
    seed: int = 0,
    *,
    max_steps_per_episode: int | None = None,
    author: str | None = None,
    author_email: str | None = None,
    code_permalink: str | None = None,
):
    """Record the mentor in the real environment and write a local Minari dataset.

    Each episode resets the environment (a MiniGrid world: to its layout, :meth:`reset_env`; a
    toy-text world: ``reset(seed=seed + episode)``), then the mentor acts: at a decision it takes
    ``mentor.option[s]``, the option's action goes to the environment's own ``step`` (with the
    world's slip, drawn from ``seed``, for a MiniGrid world), and the option stops where its
    ``β`` is 1. Observations are the world's states (``Discrete(S)``); actions, rewards (the
    environment's own), terminations and truncations are Minari's usual fields. The dataset's
    description names the world, so reading it into another world is refused.

    Args:
        world: a :func:`~himit_torch.from_minigrid` or :func:`~himit_torch.from_gymnasium`
            world made from an id.
        mentor: its :class:`~himit_torch.MentorPolicy` (e.g. :func:`~himit_torch.minigrid_mentor`).
        dataset_id: Minari's id, e.g. ``"himit/doorkey-6x6-v0"``, written under
            ``MINARI_DATASETS_PATH`` (Minari refuses an id that exists).
        episodes: how many, ``≥ 1``.
        seed: the seed of the resets (toy-text) and of the slips.
        max_steps_per_episode: give up (``ValueError``) after this many steps; default ``10·S``.
        author, author_email, code_permalink: Minari's metadata fields (where ``None``, Minari's
            warnings that recommend them are silenced).

    Returns:
        The ``minari.MinariDataset`` written.
    """
    minari = _import_minari()
    import gymnasium
    from minari.data_collector import EpisodeBuffer

    from himit_torch.worlds.minigrid import MiniGridWorld

    episodes = as_int("episodes", episodes, 1, COUNT_MAX)
    seed = as_int("seed", seed, 0, 2**63 - 1)
    limit = (
        10 * world.num_states
        if max_steps_per_episode is None
        else as_int("max_steps_per_episode", max_steps_per_episode, 1, COUNT_MAX)
    )
    if not isinstance(mentor, MentorPolicy):
        raise TypeError(f"mentor must be a MentorPolicy, got {type(mentor).__name__}")
    if mentor.options.stochastic:
        raise ValueError("demonstrations_to_minari: the mentor's options must be deterministic")
    if not isinstance(dataset_id, str) or not _DATASET_ID.match(dataset_id) or ".." in dataset_id:
        raise ValueError(
            f"dataset_id {dataset_id!r}: give a Minari id such as 'himit/doorkey-6x6-v0'"
        )
    minigrid = isinstance(world, MiniGridWorld)
    if minigrid:
        env = world.make_env()
    else:
        env_id = getattr(world, "gym_id", None)
        if env_id is None:
            raise ValueError(
                "demonstrations_to_minari records from the real environment: give a world made "
                "by from_minigrid or from_gymnasium from an id"
            )
        env = gymnasium.make(env_id, **world.gym_kwargs)
    rng = np.random.default_rng(seed)
    options, choice = mentor.options, mentor.option
    policy, beta = options.policy, options.termination
    A = int(world.num_actions)
    slip = float(getattr(world, "slip", 0.0)) if minigrid else 0.0
    buffers = []
    for e in range(episodes):
        if minigrid:
            s = world.reset_env(env)
        else:
            obs, _ = env.reset(seed=seed + e)
            s = int(obs)
        states, actions, rewards, ends, cuts = [s], [], [], [], []
        option = -1
        for _ in range(limit):
            if option < 0:
                option = int(choice[s])
                if option < 0:
                    raise ValueError(f"the mentor has no option at state {s}")
            action = int(policy[option, s])
            if slip > 0 and rng.random() < slip:  # the world's slip: another action at random
                action = int((action + 1 + rng.integers(A - 1)) % A)
            obs, reward, terminated, truncated, _ = env.step(action)
            actions.append(action)
            rewards.append(float(reward))
            ends.append(bool(terminated))
            cuts.append(bool(truncated))
            if terminated:
                # MiniGrid's success state is the world's terminal state: read it, then stop
                s = world.state_of(env) if minigrid else int(obs)
                states.append(s)
                break
            s = world.state_of(env) if minigrid else int(obs)
            states.append(s)
            if float(beta[option, s]) >= 1.0:
                option = -1
        else:
            raise ValueError(
                f"demonstrations_to_minari: episode {e} did not end within {limit} steps"
            )
        buffers.append(
            EpisodeBuffer(
                id=e,
                observations=states,
                actions=actions,
                rewards=rewards,
                terminations=ends,
                truncations=cuts,
                infos={},
            )
        )
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", r"`\w+` is set to None", UserWarning)
        # no env_spec, on purpose: the observations are the world's states, not the env's own
        warnings.filterwarnings("ignore", "env_spec is None", UserWarning)
        return minari.create_dataset_from_buffers(
            dataset_id,
            buffers,
            observation_space=gymnasium.spaces.Discrete(world.num_states),
            action_space=gymnasium.spaces.Discrete(A),
            algorithm_name="himit_torch mentor",
            author=author,
            author_email=author_email,
            code_permalink=code_permalink,
            description=_WORLD_PREFIX + json.dumps(describe_world(world), sort_keys=True),
        )
