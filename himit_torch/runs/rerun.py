"""The ``himit run`` command that rebuilds a configuration exactly (:func:`rerun_command`), the
one builder of every study's results page, and its pieces (:func:`setting_flag`,
:func:`logdir_flag`).

The flags are those that differ from the study's own configuration (its ``--quick`` one
first where that one rebuilds it with fewer flags… or only), applied as ``himit run`` applies
them: the preset first, then the settings, then the study's own adjustment (the paper's: a
shorter ``--steps`` moves ``checkpoint_every``); a flag the adjustment makes redundant is left
out. The configuration they build is compared with the given one field by field.
"""

from __future__ import annotations

import os
import shlex
from collections.abc import Callable, Sequence
from dataclasses import asdict, fields
from pathlib import Path
from typing import Any

__all__ = ["rerun_command", "setting_flag", "logdir_flag"]

#: Fields no flag of a study sets this way (the name is the run directory's; the learner's
#: fields are flags of their own; the preset is applied first).
_OWNED = ("name", "learner", "preset")


def setting_flag(name: str, value: Any) -> list[str]:
    """``himit run``'s flag for setting ``name`` at ``value`` (the cli's ``_add_setting_flags``):
    ``--name value``, ``--name a b`` for a tuple, ``none`` for None, ``--name`` / ``--no-name``
    for a switch."""
    flag = "--" + name.replace("_", "-")
    if isinstance(value, bool):
        return [flag if value else "--no-" + name.replace("_", "-")]
    if value is None:
        return [flag, "none"]
    if isinstance(value, tuple):
        return [flag, *(shlex.quote(str(v)) for v in value)]
    if isinstance(value, float):
        return [flag, repr(value)]
    return [flag, shlex.quote(str(value))]


def logdir_flag(run_dir: str | os.PathLike | None, name: str) -> list[str] | None:
    """``himit run``'s ``--logdir`` that writes run ``name`` into ``run_dir``
    (``<logdir>/<name>``): none for the default ``runs`` (or no ``run_dir``), None where
    ``run_dir`` is not named ``name`` (no ``himit run`` writes there)."""
    if run_dir is None:
        return []
    run_dir = Path(run_dir)
    if run_dir.name != name:
        return None
    return [] if run_dir.parent == Path("runs") else ["--logdir", shlex.quote(str(run_dir.parent))]


def rerun_command(
    study: str,
    base: Any,
    config: Any,
    run_dir: str | os.PathLike | None = None,
    names: Sequence[str] | None = None,
    quick: bool = False,
    adjust: Callable[[Any, frozenset[str]], Any] | None = None,
    config_file: bool = False,
) -> str | None:
    """The ``himit run study`` command that rebuilds ``config`` exactly from ``base`` (the
    configuration the command starts from), or None where none can.

    Args:
        names: the settings (the study's, then the learner's) the command may give; None:
            every setting but ``name`` (and the learner's ``window``, the study's).
        quick: try ``--quick`` (``base.quick()``) too, where ``base`` does not rebuild it.
        adjust: the study's change of a configuration built from flags, given their names.
        config_file: where no flags rebuild it, ``--config <run_dir>/config.json``.
        run_dir: ``<logdir>/<name>``: adds ``--logdir`` unless it is the default ``runs``;
            None where it is not named ``config.name``.
    """
    logdir = logdir_flag(run_dir, config.name)
    if logdir is None:
        return None
    for start in (base, base.quick()) if quick else (base,):
        flags = _flags_rebuilding(start, config, names, adjust)
        if flags is not None:
            head = ["--quick"] if start is not base else []
            return " ".join(["himit", "run", study, *head, *flags, *logdir])
    if not config_file:
        return None
    where = Path(run_dir) / "config.json" if run_dir is not None else Path("config.json")
    return " ".join(["himit", "run", study, "--config", shlex.quote(str(where)), *logdir])


def _flags_rebuilding(base: Any, config: Any, names, adjust) -> list[str] | None:
    """The flags that turn ``base`` into ``config`` (see :func:`rerun_command`), or None."""
    flags: list[str] = []
    try:
        preset = getattr(config, "preset", None)
        if (names is None or "preset" in names) and preset != getattr(base, "preset", None):
            flags += setting_flag("preset", preset)
            base = base.with_settings({"preset": preset})
        own = {f.name: getattr(config, f.name) for f in fields(config) if f.name not in _OWNED}
        changes = {n: v for n, v in own.items() if _wanted(n, names) and v != getattr(base, n)}
        learner = {
            f.name: getattr(config.learner, f.name)
            for f in (fields(config.learner) if hasattr(config, "learner") else ())
            if f.name not in config.derived_learner
            and _wanted(f.name, names)
            and getattr(config.learner, f.name) != getattr(base.learner, f.name)
        }

        def rebuilt(given: dict) -> Any:
            built = base.with_settings(given, learner)
            return adjust(built, frozenset(given)) if adjust is not None else built

        if not _builds(rebuilt, changes, config):
            return None
    except (ValueError, TypeError):
        return None
    for name in list(changes):  # a flag the study's adjustment derives is left out
        fewer = {n: v for n, v in changes.items() if n != name}
        if _builds(rebuilt, fewer, config):
            changes = fewer
    for name, value in {**changes, **learner}.items():
        flags += setting_flag(name, value)
    return flags


def _builds(rebuilt: Callable[[dict], Any], changes: dict, config: Any) -> bool:
    """Whether the flags ``changes`` build ``config`` (False where they build no valid one)."""
    try:
        return asdict(rebuilt(changes)) == asdict(config)
    except (ValueError, TypeError):
        return False


def _wanted(name: str, names: Sequence[str] | None) -> bool:
    return names is None or name in names
