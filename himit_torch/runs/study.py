"""What every study shares: its configuration's common settings (:class:`RunConfig`), the
:class:`Study` protocol and :func:`run_study`, the run directory's life around a study's batches,
its records' readers and writers, and its registry entry (:class:`StudyEntry`, listed in
:mod:`himit_torch.runs.studies`): what the command line knows of it.

A study's configuration takes each shared setting it has with :meth:`RunConfig.shared` (the
declaration in :class:`RunSettings`, the default its own), keeping its fields in its own order
so that saved ``config.json`` files and ``himit run`` commands read as they did."""

from __future__ import annotations

import csv
import dataclasses
import io
import json
import math
import os
import re
from collections import Counter
from collections.abc import Callable, Iterator, Sequence
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any, ClassVar, Protocol, TypeVar

from himit_torch.learner.config import LearnerConfig
from himit_torch.learner.engines import ENGINES
from himit_torch.learner.presets import PRESETS, apply_preset, check_preset
from himit_torch.runs.rerun import rerun_command
from himit_torch.runs.runner import check_run_dir, clear_run_dir, write_atomically
from himit_torch.validation import (
    as_device,
    check_settings,
    parse_document,
    read_text,
    refuse_unknown_fields,
    setting,
)

__all__ = [
    "RunSettings",
    "RunConfig",
    "Study",
    "StudyEntry",
    "RunFlags",
    "InfoTopic",
    "run_study",
    "prepare_run_dir",
    "check_resumed_config",
    "config_differences",
    "read_table",
    "write_rows",
    "series_of",
    "Field",
    "check_record",
    "read_record",
    "read_config",
    "read_config_file",
    "read_config_fields",
    "run_each",
    "option_kinds_text",
]


@dataclass
class RunSettings:
    """The settings every study's configuration shares, each declared once (the
    defaults here are the paper's experiments'; a study gives its own with :meth:`RunConfig.shared`)."""

    name: str = setting(
        "run", folder=True, doc="The run's name: its run directory's (``<logdir>/<name>``)."
    )
    seeds: int = setting(5, ge=1, doc="Runs per agent (or condition) of each batch.")
    first_seed: int = setting(
        0,
        ge=0,
        doc="""
        Seeds are first_seed … first_seed + seeds − 1 (a seed also picks its mentor
        episodes).""",
    )
    steps: int = setting(200_000, ge=1, doc="Primitive steps per run.")
    mentor_episodes: int = setting(
        20, ge=1, doc="Mentor episodes recorded (states only) per seed before learning."
    )
    window: int = setting(
        5000,
        ge=1,
        doc="""
        Goals are counted per window of this many steps (the paper's 5000), and the run's
        per-window measures taken; also the learner's ``window``.""",
    )
    engine: str = setting(
        "auto",
        choices=ENGINES,
        doc="""
        Which engine carries out the ticks: ``auto`` (the compiled ``numba`` loop on a CPU, the
        ``torch`` engine on a GPU), ``numba`` or ``torch``. Both give the same curves.""",
    )
    device: str = setting(
        "cpu",
        hint="a torch device such as 'cpu' or 'cuda'",
        doc="Where the batches run (``cpu`` or ``cuda``).",
    )
    preset: str | None = setting(
        None,
        choices=tuple(PRESETS),
        doc="""
        The named preset the learner settings follow (``himit_torch.learner.presets``):
        ``paper`` (eq. 2 as the paper states it), ``explore-goals`` (the paper's with ε held
        until the 10th goal: an exploration schedule, for every agent), ``mentor-fade`` (the
        paper's with the mentor term fading: read only by agents with a mentor term),
        ``recommended`` (both) or ``subgoal-mentor`` (``mentor-fade`` with the segment term and
        trial: for a mentor seen only at its subgoals); ``None``: none claimed. Every agent of
        a run gets it: compare methods under one preset. Set by ``with_preset`` / ``himit run --preset``; a
        configuration whose learner departs from its preset's settings is refused. The greedy
        tie rule is not part of a preset (``--tie-break``).""",
    )
    learner: LearnerConfig = setting(
        default_factory=LearnerConfig,
        doc="Learner settings (``LearnerConfig``; a dict of its fields is accepted).",
    )
    mentor_goal: str = setting(
        "same",
        choices=("same", "top-right"),
        doc="""
        What the mentor demonstrates (default ``same``: the learner's task). ``top-right``: its
        walk to the top-right corner cell ``(0, N − 1)`` (the detour's waypoint, on no
        shortest path to the learner's goal), ending there: a mentor demonstrating another goal
        than the learner's.""",
    )


#: The shared declarations, by name.
_SHARED = {f.name: f for f in dataclasses.fields(RunSettings)}

Config = TypeVar("Config", bound="RunConfig")


class RunConfig:
    """The base of every study's configuration (a dataclass of
    :func:`~himit_torch.validation.setting` fields)."""

    @staticmethod
    def shared(
        name: str,
        default: Any = dataclasses.MISSING,
        *,
        default_factory: Any = dataclasses.MISSING,
        doc: str | None = None,
    ) -> Any:
        """The shared setting ``name`` of :class:`RunSettings` as a field of a
        study's configuration: its declaration (or ``doc``, in the study's words) with the study's
        ``default`` or ``default_factory`` (neither: the shared default)."""
        base = _SHARED[name]
        if default is dataclasses.MISSING and default_factory is dataclasses.MISSING:
            default, default_factory = base.default, base.default_factory
        metadata = dict(base.metadata)
        if doc is not None:
            (key,) = metadata
            metadata[key] = replace(metadata[key], doc=" ".join(doc.split()))
        return dataclasses.field(
            default=default, default_factory=default_factory, metadata=metadata
        )

    def check_run_settings(self) -> None:
        """Check every declared field
        (:func:`~himit_torch.validation.check_settings`), then the shared rules: the learner follows
        the preset, the device is written well, the derived learner settings are set."""
        check_settings(self)
        config: Any = self  # a study's dataclass: the shared fields it has
        kind = type(self).__name__
        if hasattr(config, "learner"):
            check_preset(kind, config.learner, getattr(config, "preset", None))
        if hasattr(config, "device"):
            # Written down, not run: a config naming cuda is valid on a machine without
            # (plotting a GPU run's directory); the learner refuses it where it would run.
            as_device(f"{kind}.device", config.device, available=False)
        if hasattr(config, "learner"):
            derived = self.derived_learner_settings()
            if any(getattr(config.learner, k) != v for k, v in derived.items()):
                config.learner = replace(config.learner, **derived)
            if "mentors" not in derived and config.learner.mentors != 1:
                raise ValueError(
                    f"{kind}.learner.mentors={config.learner.mentors!r}: this study shows its "
                    "learners one demonstration set (one mentor); mentors must be 1"
                )

    #: The learner settings a study derives from its own (``derived_learner_settings``).
    derived_learner: ClassVar[tuple[str, ...]] = ("window",)

    def derived_learner_settings(self) -> dict[str, Any]:
        """The learner settings that follow from this study's own, by name: **derived and
        recorded** (set on the learner, saved in ``config.json``, no flags of their own). Here
        the learner's ``window``; a study adds its own (:attr:`derived_learner` names them)."""
        window = getattr(self, "window", None)
        return {} if window is None else {"window": window}

    def with_preset(self: Config, name: str) -> Config:
        """This configuration with preset ``name``'s learner settings, and the preset
        recorded.

        Raises:
            ValueError: ``name`` is no preset's, or the study has no learner settings."""
        config: Any = self
        kind = type(self).__name__
        if not hasattr(config, "learner"):
            raise ValueError(
                f"{kind}.with_preset({name!r}): {kind} has no learner settings for a preset to "
                "set (its learners' settings are its worlds' experiments')"
            )
        if not isinstance(name, str) or name not in PRESETS:
            raise ValueError(
                f"{kind}.with_preset: unknown preset {name!r}; presets: {', '.join(PRESETS)}"
            )
        return replace(config, preset=name, learner=apply_preset(config.learner, name))

    def with_settings(
        self: Config, settings: dict[str, Any], learner: dict[str, Any] | None = None
    ) -> Config:
        """This configuration with its own ``settings`` and the ``learner`` settings, in one
        order for every caller (``himit run``'s flags, a sweep's levels, a rerun command): a
        ``preset`` among ``settings`` first (:meth:`with_preset`; ``None`` records no preset and
        leaves the learner as it is), then the learner settings beside it, then the rest.

        Raises:
            ValueError: a setting the dataclasses refuse, or an unknown preset."""
        config: Any = self
        changes = dict(settings)
        if "preset" in changes:
            preset = changes.pop("preset")
            config = replace(config, preset=None) if preset is None else config.with_preset(preset)
        if learner:
            changes["learner"] = replace(config.learner, **learner)
        return replace(config, **changes)

    @property
    def seed_list(self) -> list[int]:
        """The seeds: ``first_seed`` … ``first_seed + seeds − 1``."""
        first, n = self.first_seed, self.seeds  # type: ignore[attr-defined]
        return list(range(first, first + n))

    def to_json(self) -> str:
        """The configuration as ``config.json`` holds it."""
        return json.dumps(asdict(self), indent=2)  # type: ignore[call-overload]

    def quick(self: Config) -> Config:
        """A tiny budget of the same study (``himit run … --quick``); by default the
        study as it is."""
        return self


def read_config(cls: type[Config], data: Any, where: str) -> Config:
    """A ``cls`` from ``data`` (a parsed ``config.json``); unknown fields or refused
    values are a ``ValueError`` naming ``where``, a field not named takes its default."""
    if not isinstance(data, dict):
        raise ValueError(f"{where} holds a {type(data).__name__}, not a configuration")
    refuse_unknown_fields(data, cls, where)
    try:
        return cls(**data)
    except (ValueError, TypeError) as err:
        raise ValueError(f"{where}: {err}") from None


def read_config_file(
    cls: type[Config], path: str | os.PathLike, where: str | None = None
) -> Config:
    """A ``cls`` from the JSON file ``path`` (:func:`read_config`); an unreadable
    file is a ``ValueError`` naming ``where`` (default: ``config file <path>``)."""
    where = where or f"config file {path}"
    return read_config(cls, parse_document(where, read_text(where, Path(path)), "json"), where)


def read_config_fields(path: str | os.PathLike, where: str) -> set[str]:
    """The field names of the JSON object in ``path`` (a ``ValueError`` naming
    ``where`` if it holds none)."""
    data = parse_document(where, read_text(where, Path(path)), "json")
    if not isinstance(data, dict):
        raise ValueError(f"{where} holds a {type(data).__name__}, not a configuration")
    return set(data)


_WHOLE = re.compile(r"-?[0-9]+")


def read_table(
    path: Path,
    where: str,
    whole: Sequence[str],
    numbers: Sequence[str] = (),
    text: Sequence[str] = (),
    fix: str = "",
) -> list[dict[str, str]]:
    """The rows of a run's CSV record at ``path``, refused unless a page can be drawn
    from them: UTF-8 CSV, the columns ``whole`` (whole numbers), ``numbers`` (finite, or empty) and
    ``text`` present, every row as long as the header, at least one row.

    Raises:
        ValueError: naming ``where`` and, where one is at fault, the line and column; ``fix`` is
            appended."""
    reader = csv.reader(io.StringIO(read_text(where, path), newline=""))
    try:
        header = next(reader, [])
        missing = [key for key in (*text, *whole, *numbers) if key not in header]
        if missing:
            raise ValueError(f"{where}: columns {missing} are missing{fix}")
        rows = []
        for row in reader:
            if len(row) != len(header):
                raise ValueError(
                    f"{where}, line {reader.line_num}: {len(row)} cells, not {len(header)}{fix}"
                )
            cells = dict(zip(header, row))
            for key in whole:
                if not _WHOLE.fullmatch(cells[key]):
                    raise ValueError(
                        f"{where}, line {reader.line_num}: {key}={cells[key]!r:.60} is not a "
                        f"whole number{fix}"
                    )
            for key in numbers:
                if cells[key] and not _is_finite(cells[key]):
                    raise ValueError(
                        f"{where}, line {reader.line_num}: {key}={cells[key]!r:.60} is not a "
                        f"finite number{fix}"
                    )
            rows.append(cells)
    except csv.Error as err:
        raise ValueError(
            f"{where}, line {reader.line_num}: not CSV a run writes ({err}){fix}"
        ) from None
    if not rows:
        raise ValueError(f"{where} holds no rows{fix}")
    return rows


def write_rows(
    path: Path, columns: Sequence[str], rows: Sequence[dict], newline: str = "\r\n"
) -> None:
    """A run's CSV record at ``path`` (its folder made): ``columns``, then ``rows``, floats
    to 6 significant digits, each line ending with ``newline`` (``csv``'s own ``\\r\\n``, or
    ``\\n``); written atomically."""
    path.parent.mkdir(parents=True, exist_ok=True)
    text = io.StringIO()
    out = csv.DictWriter(text, fieldnames=columns, lineterminator=newline)
    out.writeheader()
    for r in rows:
        out.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})
    write_atomically(path, text.getvalue())


def _is_finite(text: str) -> bool:
    try:
        return math.isfinite(float(text))
    except ValueError:
        return False


def series_of(
    rows: Sequence[dict[str, str]], value: str, where: str, fix: str = ""
) -> tuple[list[int], list[list[float]]]:
    """``(steps, per seed its values)`` from one batch's rows (``seed``, ``step``,
    ``value``), seeds in order; seeds recorded at different steps are a ``ValueError`` naming
    ``where``."""
    by_seed: dict[int, list[tuple[int, float]]] = {}
    for r in rows:
        by_seed.setdefault(int(r["seed"]), []).append((int(r["step"]), float(r[value] or "nan")))
    series = [sorted(v) for _, v in sorted(by_seed.items())]
    steps = [step for step, _ in series[0]]
    for seed, points in zip(sorted(by_seed), series):
        at = [step for step, _ in points]
        if len(set(at)) != len(at):
            raise ValueError(f"{where}: seed {seed} has a row twice at one step{fix}")
        if at != steps:
            raise ValueError(
                f"{where}: seed {seed}'s rows are at other steps than seed {min(by_seed)}'s "
                f"({len(at)} rows, not {len(steps)}){fix}"
            )
    return steps, [[v for _, v in points] for points in series]


# ============================================================================ the JSON records
def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


#: The kinds of value a record's field may hold: each one's test and name.
_KINDS: dict[str, tuple[Callable[[Any], bool], str]] = {
    "text": (lambda v: isinstance(v, str), "a string"),
    "whole": (lambda v: _is_number(v) and isinstance(v, int), "a whole number"),
    "number": (_is_number, "a number"),
    "finite": (lambda v: _is_number(v) and math.isfinite(v), "a finite number"),
    "number?": (lambda v: v is None or _is_number(v), "a number or null"),
    "list": (lambda v: isinstance(v, list), "a list"),
    "object": (lambda v: isinstance(v, dict), "an object"),
    "any": (lambda v: True, "anything"),
}


@dataclass(frozen=True)
class Field:
    """What one field of a run's JSON record must hold (:func:`check_record`): a value of
    ``kind`` (a key of ``_KINDS``), a number ``> above`` and finite where ``above`` is given;
    ``per_run``: a list of one value of that kind per run (``or_empty``: or empty, not measured);
    ``items``: the fields of an object, or of each object in a non-empty list; ``optional``: it
    may be absent."""

    kind: str = "any"
    above: float = -math.inf
    per_run: str | None = None
    or_empty: bool = False
    items: dict[str, Field] | None = None
    optional: bool = False

    def fault(self, value: Any, runs: int | None) -> str | None:
        """What the field must do (``be a number > 0``, ``hold one number per run (4)``) where
        ``value`` does not, else None."""
        test, kind = _KINDS[self.kind]
        bounded = math.isfinite(self.above)
        if not test(value) or (bounded and not self.above < value < math.inf):
            return f"be {kind}" + (f" > {self.above:g}" if bounded else "")
        if self.per_run is not None:
            item_test, item = _KINDS[self.per_run]
            if len(value) not in ((0, runs) if self.or_empty else (runs,)) or not all(
                item_test(v) for v in value
            ):
                return (
                    f"hold one {item.split(' ', 1)[1]} per run ({runs})"
                    + " or none" * self.or_empty
                )
        if self.items is not None and self.kind == "list":
            if not value or not all(isinstance(v, dict) for v in value):
                return "be a non-empty list of objects"
        return None


def check_record(data: Any, schema: dict[str, Field], where: str, fix: str, runs=None) -> None:
    """Refuse a run's JSON record ``data`` unless it is an object holding what ``schema``
    declares: a ``ValueError`` ``<where>: field '<name>' is missing<fix>`` or ``… must <be
    what>, got <value><fix>`` (``batches[0].steps`` in a list of objects). ``runs``: the length
    of the ``per_run`` lists, or the name of a field that lists the runs' agents."""
    if not isinstance(data, dict):
        raise ValueError(f"{where} holds a JSON {type(data).__name__}, not an object{fix}")
    if isinstance(runs, str):
        if runs not in data:
            raise ValueError(f"{where}: field {runs!r} is missing{fix}")
        names = data[runs]
        if not (isinstance(names, list) and names and all(isinstance(n, str) for n in names)):
            raise ValueError(f"{where}: field {runs!r} must name one agent per run{fix}")
        runs = len(names)
    _check_fields(data, schema, where, fix, runs, "")


def _check_fields(data: dict, schema, where: str, fix: str, runs, prefix: str) -> None:
    for name, spec in schema.items():
        if name not in data:
            if spec.optional:
                continue
            raise ValueError(f"{where}: field {prefix + name!r} is missing{fix}")
        value, field = data[name], prefix + name
        what = spec.fault(value, runs)
        if what is not None:
            raise ValueError(f"{where}: field {field!r} must {what}, got {value!r:.60}{fix}")
        if spec.items is not None and isinstance(value, dict):
            _check_fields(value, spec.items, where, fix, runs, f"{field}.")
        for i, item in enumerate(
            value if spec.items is not None and isinstance(value, list) else ()
        ):
            _check_fields(item, spec.items, where, fix, runs, f"{field}[{i}].")


def read_record(path: Path, where: str, schema: dict[str, Field], fix: str, runs=None) -> Any:
    """The JSON record at ``path``, parsed and checked (:func:`check_record`); an unreadable
    file is a ``ValueError`` naming ``where`` too."""
    data = parse_document(where, read_text(where, path), "json")
    check_record(data, schema, where, fix, runs)
    return data


#: ``himit info`` counts goals per this many steps, for every world (the paper's window).
INFO_WINDOW = 5000


def optimum_lines(
    world: Any, learner: Any, mentor: Any, window: int = INFO_WINDOW
) -> tuple[list[str], int]:
    """``himit info``'s table of optimal trips (primitives, the learner's options,
    the mentor's own policy; each exact), and the width of its first column."""
    from himit_torch.exact.greedy_evaluation import evaluate_option_choice
    from himit_torch.exact.optimum import option_optimum, primitive_optimum

    rows = [
        ("primitives only", primitive_optimum(world, window).evaluation),
        ("learner's options", option_optimum(world, learner, window)),
        (
            f"mentor (prefers its options within {mentor.tolerance:g})",
            evaluate_option_choice(world, mentor.options, mentor.option, window),
        ),
    ]
    width = max(len(name) for name, _ in rows) + 2
    lines = [
        "",
        f"{'optimal policy':<{width}}{'steps start→goal':>18}{f'goals / {window} steps':>22}",
    ]
    for name, trip in rows:
        steps, goals = float(trip.steps_per_episode[0]), float(trip.goals_per_window[0])
        lines.append(f"{name:<{width}}{steps:>18.1f}{goals:>22.1f}")
    return lines, width


def option_kinds_text(options: Any) -> str:
    """How many options of each kind ``options`` holds, e.g. ``4 primitive, 180 doorway``."""
    return ", ".join(f"{n} {kind}" for kind, n in Counter(options.kinds).items())


# ============================================================================ the registry entry
@dataclass(frozen=True)
class RunFlags:
    """The run flags of ``himit run`` a study's runner reads."""

    resume: bool = False
    force: bool = False
    progress: bool = True
    workers: int | None = None


@dataclass(frozen=True)
class InfoTopic:
    """What ``himit info`` says of a study's worlds: chosen by ``flag`` (``None``: the
    default topic), its flags added by ``add_flags``, ``requires`` the flags that need ``flag``,
    ``show`` the lines it prints."""

    flag: str | None
    add_flags: Callable[[Any], None]
    show: Callable[[Any], Iterator[str]]
    requires: tuple[str, ...] = ()


@dataclass(frozen=True)
class StudyEntry:
    """One study as the command line knows it (``himit run NAME``, ``himit plot``,
    ``himit info``); the entries are listed in :mod:`himit_torch.runs.studies`."""

    name: str
    """``himit run NAME``."""
    help: str
    """Its one-line help."""
    config_class: type
    """Its configuration (a :class:`RunConfig` dataclass): one flag per declared setting (the
    learner's too, where it has one)."""
    configs: Callable[[], tuple[Any, ...]]
    """The configurations ``himit run NAME`` starts from (one, or several run as one pool:
    ``himit run paper``)."""
    run: Callable[[Sequence[tuple[Any, Path]], RunFlags], Any]
    """Runs the ``(config, run_dir)`` plans with the :class:`RunFlags`."""
    describe: Callable[[Any, Path], str]
    """The line printed before a plan runs."""
    redraw: Callable[[Path], None] | None = None
    """``himit plot``'s redraw of a finished run directory (``None``: not redrawn)."""
    no_redraw: str = ""
    """Why ``himit plot`` does not redraw its run directories (``redraw`` is ``None``)."""
    flag_defaults: Callable[[], Any] | None = None
    """The configuration whose values the flags show (default: the first of ``configs``)."""
    adjust: Callable[[Any, frozenset[str]], Any] | None = None
    """A change of the configuration built from the flags, given the names of the settings
    given (the paper's: a shorter ``--steps`` moves ``checkpoint_every``)."""
    run_flags: tuple[str, ...] = ()
    """Which of ``config`` (a saved ``config.json`` in place of the defaults), ``resume`` and
    ``workers`` it takes."""
    skip: tuple[str, ...] = ()
    """Settings that are not flags."""
    info: InfoTopic | None = None
    """What ``himit info`` says of its worlds."""
    rerun_flags: tuple[str, ...] | None = None
    """The settings its results page's ``himit run`` command may give as flags (``None``:
    every one); with ``rerun_flags``, ``--quick`` is tried too."""
    rerun_config_file: bool = False
    """Where no flags rebuild a configuration, ``--config <run_dir>/config.json``."""

    def defaults(self) -> Any:
        """The configuration whose values the flags show."""
        return self.flag_defaults() if self.flag_defaults else self.configs()[0]

    def run_command(self, config: Any, run_dir: str | os.PathLike | None = None) -> str | None:
        """The ``himit run NAME`` command that rebuilds ``config`` exactly from
        :meth:`defaults`, or None where none can
        (:func:`~himit_torch.runs.rerun.rerun_command`)."""
        return rerun_command(
            self.name,
            self.defaults(),
            config,
            run_dir,
            self.rerun_flags,
            quick=self.rerun_flags is not None,
            adjust=self.adjust,
            config_file=self.rerun_config_file,
        )


def run_each(
    runner: Callable[..., Any], resume: bool = False
) -> Callable[[Sequence[tuple[Any, Path]], RunFlags], None]:
    """A :attr:`StudyEntry.run` calling ``runner(config, run_dir, force=…, progress=…)``
    (and ``resume=…`` where ``resume``) for each plan."""

    def run(plans: Sequence[tuple[Any, Path]], flags: RunFlags) -> None:
        extra = {"resume": flags.resume} if resume else {}
        for config, run_dir in plans:
            runner(config, run_dir, force=flags.force, progress=flags.progress, **extra)

    return run


# ================================================================================ the protocol
class Study(Protocol):
    """A study: what :func:`run_study` needs to run one into a run directory.

    ``config_class`` is its configuration; ``folders`` and ``files`` what its run directory
    holds (what ``force`` clears)."""

    config_class: ClassVar[type]
    folders: ClassVar[tuple[str, ...]]
    files: ClassVar[tuple[str, ...]]

    def run(self, config: Any, run_dir: Path, resume: bool, progress: bool) -> Any:
        """Run every batch of ``config`` into ``run_dir``; return what :meth:`report` reads."""

    def report(self, config: Any, run_dir: Path, results: Any) -> None:
        """Write the figures and ``results.md`` of a finished run."""


def run_study(
    study: Study,
    config: Any,
    run_dir: str | os.PathLike,
    resume: bool | None = False,
    force: bool = False,
    progress: bool = True,
    check: Callable[[], None] | None = None,
    resume_hint: str = "resume with the same flags",
    load: Callable[[Path], Any] | None = None,
) -> Any:
    """Run ``study`` with ``config`` into ``run_dir`` and write its report.

    A finished run is refused unless ``force`` (which clears the study's folders and files) or
    ``resume`` (the saved ``config.json`` must equal ``config``); ``check`` runs before anything is
    touched.

    Args:
        resume: continue an interrupted run; ``False``: an unfinished run is refused; ``None``: the
            study cannot resume, an unfinished run starts over.
        resume_hint, load: as :func:`prepare_run_dir`.

    Returns:
        What the study's :meth:`Study.run` returned."""
    kind = getattr(study, "config_class", None)
    if isinstance(kind, type) and not isinstance(config, kind):
        raise TypeError(
            f"run_study: config={config!r:.60} must be of type {kind.__name__} (the study's "
            "configuration)"
        )
    if not isinstance(run_dir, (str, os.PathLike)):
        raise TypeError(f"run_study: run_dir={run_dir!r:.60} must be a path (str or Path)")
    for name, value in (("resume", resume), ("force", force), ("progress", progress)):
        if not isinstance(value, bool) and not (name == "resume" and value is None):
            raise TypeError(
                f"run_study: {name}={value!r:.60} must be True or False"
                + (" (or None)" if name == "resume" else "")
            )
    run_dir = Path(run_dir)
    if check is not None:
        check()
    check_run_dir(run_dir, force=force, resume=resume)
    prepare_run_dir(
        run_dir,
        config,
        bool(resume),
        force,
        study.folders,
        study.files,
        resume_hint=resume_hint,
        load=load,
    )
    results = study.run(config, run_dir, bool(resume), progress)
    study.report(config, run_dir, results)
    return results


def config_differences(saved: Any, given: Any) -> list[str]:
    """The settings where ``given`` departs from ``saved``, each as
    ``name: saved …, given …`` (the learner's as ``learner.<field>``); what a refused resume names."""
    return _dict_differences(asdict(saved), asdict(given), "")


def _dict_differences(saved: dict, given: dict, prefix: str) -> list[str]:
    differences = []
    for key in [*given, *(k for k in saved if k not in given)]:
        mine, theirs = saved.get(key, "(none)"), given.get(key, "(none)")
        if isinstance(mine, dict) and isinstance(theirs, dict):
            differences += _dict_differences(mine, theirs, f"{prefix}{key}.")
        elif mine != theirs:
            differences.append(f"{prefix}{key}: saved {mine!r:.100}, given {theirs!r:.100}")
    return differences


def prepare_run_dir(
    run_dir: Path,
    config: Any,
    resume: bool,
    force: bool,
    folders: Sequence[str],
    files: Sequence[str],
    resume_hint: str = "resume with the same flags",
    load: Callable[[Path], Any] | None = None,
) -> None:
    """Clear (``force``: ``folders`` and ``files``) or check (``resume``:
    :func:`check_resumed_config`) ``run_dir``, and save ``config`` in it."""
    if resume and not force:  # (--force starts over: nothing of the old run is kept)
        check_resumed_config(run_dir, config, resume_hint, load)
    if force:
        clear_run_dir(run_dir, folders, files)
    run_dir.mkdir(parents=True, exist_ok=True)
    write_atomically(run_dir / "config.json", config.to_json())


def check_resumed_config(
    run_dir: Path,
    config: Any,
    resume_hint: str = "resume with the same flags",
    load: Callable[[Path], Any] | None = None,
) -> None:
    """Refuse to resume ``run_dir`` with ``config`` when its saved
    ``config.json`` (read by ``load``, default through ``config``'s class) differs: a ``ValueError``
    naming each differing setting and ``resume_hint``. Reads only."""
    cfg_path = Path(run_dir) / "config.json"
    if not cfg_path.exists():
        return
    where = f"--resume: {cfg_path}"
    saved = load(cfg_path) if load else read_config_file(type(config), cfg_path, where)
    differences = config_differences(saved, config)
    if differences:
        raise ValueError(
            f"--resume: {cfg_path} holds a different configuration than the one given "
            f"({'; '.join(differences)}); {resume_hint} or start over with --force"
        )
