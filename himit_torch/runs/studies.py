"""The studies of ``himit run``, listed once: each is its module's
:class:`~himit_torch.runs.study.StudyEntry` (its name, help, configuration class, runner,
``himit plot`` redraw and ``himit info`` topic). The command line knows no study but through
this registry; a new study is its module and one line here (or :func:`register`, e.g. from a
test or a notebook).

``himit plot`` finds a run directory's study from its ``config.json``
(:func:`study_of_run_dir`): the first study, in the order listed, whose configuration class
has every field the file names.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

from himit_torch.runs import discovery, experiment, gymnasium, puzzle_box
from himit_torch.runs.study import InfoTopic, StudyEntry, read_config_fields

__all__ = ["STUDIES", "info_topics", "register", "study_of_run_dir"]

#: The studies, by name, in the order ``himit run --help`` lists them.
STUDIES: dict[str, StudyEntry] = {}


def register(entry: StudyEntry) -> StudyEntry:
    """Add ``entry`` to :data:`STUDIES` (a name already taken is a ``ValueError``)."""
    if entry.name in STUDIES:
        raise ValueError(f"a study named {entry.name!r} is already registered")
    STUDIES[entry.name] = entry
    return entry


for _entry in (
    *experiment.ENTRIES,
    gymnasium.ENTRY,
    gymnasium.MINIGRID_ENTRY,
    discovery.ENTRY,
    puzzle_box.ENTRY,
):
    register(_entry)


def info_topics() -> list[InfoTopic]:
    """Every study's ``himit info`` topic, in the order the studies are listed."""
    return [e.info for e in STUDIES.values() if e.info is not None]


def study_of_run_dir(run_dir: Path) -> StudyEntry:
    """The study whose run directory ``run_dir`` is, from the fields of its ``config.json``.

    Raises:
        ValueError: ``config.json`` is missing or holds no configuration, or no study's
            configuration has all its fields; the message names the file.
    """
    path = run_dir / "config.json"
    where = f"himit plot: {path}"
    saved = read_config_fields(path, where)
    for entry in STUDIES.values():
        if saved <= {f.name for f in dataclasses.fields(entry.config_class)}:
            return entry
    raise ValueError(
        f"{where} is no study's configuration (fields {sorted(saved)}); studies: "
        + ", ".join(STUDIES)
    )
