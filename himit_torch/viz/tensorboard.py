"""TensorBoard logs of a batch of runs: one event folder per run (CleanRL-style names), scalars
that say what they are, maps during training, and hyperparameters that group seeds.

Used by the runners of :mod:`himit_torch.runs` (``himit run``: the paper's experiments and
Gymnasium) and the notebooks, so every run directory reads the same in TensorBoard:

* **One run, one folder, one history.** A folder that already holds events is refused (or, with
  ``overwrite=True``, emptied first), so a second run never appends its steps to an earlier run's
  curve. Continuing a checkpointed run (``resume_step``) purges what the interrupted run logged
  after its checkpoint, so the resumed curve is the uninterrupted one.
* **Scalars with descriptions** (:data:`SCALAR_DESCRIPTIONS`, shown by TensorBoard beside each
  chart): what the number is, per window or cumulative.
* **Maps during training** (:meth:`TensorBoardLogger.maps`) for the runs chosen, with colorbars
  and legends (:class:`~himit_torch.viz.plotting.MapRenderer`).
* **Hyperparameters without the seed**: runs with the same settings form one session group in
  the HParams dashboard, so the seeds of one agent are compared as a group.
"""

from __future__ import annotations

import math
import os
import shlex
import shutil
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import torch

__all__ = ["TensorBoardLogger", "SCALAR_DESCRIPTIONS", "IMAGE_DESCRIPTIONS", "tensorboard_command"]


def _shell_path(path: Path) -> str:
    """``path`` as typed in a shell from the current folder (relative when below it)."""
    try:
        text = str(path.relative_to(Path.cwd()))
        text = text if "/" in text else f"./{text}"
    except ValueError:
        text = str(path)
    return shlex.quote(text)


def tensorboard_command(logdir: str | os.PathLike) -> str:
    """The command that starts TensorBoard on ``logdir``, as it works typed from the current
    folder: ``tensorboard`` when it is on ``PATH``, else the ``tensorboard`` script beside this
    Python (``.venv/bin/tensorboard`` in the project's virtual environment), else
    ``<this python> -m tensorboard.main``."""
    log = shlex.quote(str(logdir))
    if shutil.which("tensorboard") is not None:
        return f"tensorboard --logdir {log}"
    beside = Path(sys.executable).parent / "tensorboard"
    if beside.is_file() and os.access(beside, os.X_OK):
        return f"{_shell_path(beside)} --logdir {log}"
    return f"{_shell_path(Path(sys.executable))} -m tensorboard.main --logdir {log}"


def _png(rgb: np.ndarray):
    """An ``[H, W, 3]`` uint8 image as TensorBoard's image proto, PNG-encoded at zlib's fastest
    level: the same pixels as ``torch.utils.tensorboard.summary.make_image`` (which resizes to
    the same size with Lanczos first, a copy, then encodes at the default level), in ≈ half its
    time (a map of the 80 × 80 world: 9 against 16 ms; a few more bytes)."""
    import io

    from PIL import Image
    from tensorboard.compat.proto.summary_pb2 import Summary

    height, width, channels = rgb.shape
    encoded = io.BytesIO()
    Image.fromarray(rgb).save(encoded, format="PNG", compress_level=1)
    return Summary.Image(
        height=height, width=width, colorspace=channels, encoded_image_string=encoded.getvalue()
    )


#: What each scalar tag holds; written into the event files as the tag's description.
SCALAR_DESCRIPTIONS = {
    "charts/goals_in_window": "Goals reached in the window of steps that ends at this step "
    "(per window, not cumulative; the paper's curves).",
    "charts/goals_total": "Goals reached since the start of the run (cumulative).",
    "charts/first_goal_step": "Step at which the run first reached the goal, logged once, at that "
    "step (x = y). No point: not found yet.",
    "charts/episodes_in_window": "Episodes ended in the window of steps that ends at this step "
    "(per window; any terminal state, e.g. FrozenLake's holes too).",
    "charts/epsilon": "Exploration rate ε at the end of the window (ε-greedy over the run's own "
    "options; decays only after the first goal).",
    "charts/episodes": "Episodes finished since the start (cumulative; an episode ends at the "
    "goal).",
    "charts/steps_per_episode": "Mean primitive steps of the episodes that ended in this window "
    "(per window; absent when none ended).",
    "planner/backups": "Bellman backups done since the start (cumulative).",
    "planner/decisions": "Option choices made since the start (cumulative).",
    "eval/greedy_value_gap": "V*(μ) − V^π(μ): how far the run's greedy option policy now is from "
    "the optimum, both exact on the true model from the start distribution (0 = optimal).",
    "eval/greedy_goals_per_window": "Goals per window of the run's greedy policy frozen now (ε = 0 "
    "over its own options, ties as configured), exact on the true model: the long-run rate of "
    "episode after episode (himit_torch.exact.greedy_evaluation). Not what the run scored: "
    "see charts/goals_in_window.",
    "eval/greedy_percent_of_optimal": "eval/greedy_goals_per_window as a % of the optimal "
    "policy's rate (exact, primitive actions).",
    "eval/greedy_percent_of_mentor": "eval/greedy_goals_per_window as a % of the mentor's own "
    "rate (its policy over its own options, exact).",
    "eval/greedy_reach_share": "Share of start states (weighted by the start distribution) "
    "from which the frozen greedy policy reaches the goal with probability 1.",
    "eval/greedy_value_start": "V^π(start) of the frozen greedy policy, exact on the true model "
    "(compare model/value_start_true); logged at the end of the run.",
    "model/coverage": "Share of the run's usable (state, option) pairs it has tried at least "
    "once, now.",
    "model/value_start": "V(start): the value the run's planner gives the start state now "
    "(compare model/value_start_true).",
    "model/value_start_true": "V*(start): the optimal value of the start state, exact from the "
    "world's true model (primitive actions); a constant reference for "
    "model/value_start — above it, the run is optimistic.",
    "mentor/term_wins": "Share of the mentor's observed states where the mentor term is the max "
    "of eq. 2, now (imitating runs only).",
    "hparam/total_goals": "Goals reached over the whole run (cumulative; the HParams metric).",
    "hparam/final_window_goals": "Goals in the run's last window (the HParams metric).",
    "hparam/first_goal_step": "Step of the run's first goal; the run's length + 1 if it never "
    "found it (the HParams metric).",
    "hparam/value_start": "V(start) at the end of the run (the HParams metric).",
    "hparam/greedy_percent_of_mentor": "The frozen greedy policy's goal rate at the end as a % "
    "of the mentor's own, exact (the HParams metric).",
}

#: What each map shows; written as the image tag's description.
IMAGE_DESCRIPTIONS = {
    "maps/values": "The run's state values V(s) at this step (colorbar). Grey: still at the "
    "initial value −1 — the value of never reaching the goal, kept until the "
    "learned model links the cell to the goal. Walls black.",
    "maps/greedy_option": "The run's greedy option per state at this step (legend): primitive "
    "direction or option kind; grey where nothing was tried. Walls black.",
    "maps/visits": "How often the run has been in each cell up to this step (log colour scale; "
    "grey: never), with the states of the mentor episodes it watched (orange).",
}


def _has_events(folder: Path) -> bool:
    return folder.is_dir() and any(folder.glob("events.out.tfevents.*"))


def _wait_past_existing_event_files(folders: Sequence[Path]) -> None:
    """Wait until the clock's second is past every event file's in ``folders``.

    TensorBoard reads a folder's event files in the order of their names,
    ``events.out.tfevents.<second>.<host>.<pid>.<counter>``: a file opened in the same second
    by the same process sorts by its counter as text (``"10"`` before ``"9"``), and a purge in
    a file read first would be undone by the file it was meant to purge. A resumed run is
    usually a new process seconds later; this matters when it is not (≤ 1 s)."""
    import time

    seconds = [
        int(part)
        for folder in folders
        for file in folder.glob("events.out.tfevents.*")
        for part in file.name.split(".")[3:4]
        if part.isdigit()
    ]
    while seconds and time.time() < max(seconds) + 1:
        time.sleep(0.02)


class TensorBoardLogger:
    """One :class:`~torch.utils.tensorboard.SummaryWriter` per run of a batch.

    Args:
        root: the folder that holds the run folders (e.g. ``<run dir>/tb``).
        names: one folder name per run, e.g. ``world40__imitation__seed0``.
        world: the world (for the maps).
        options: the learner's options (for the greedy-option map).
        true_value_start: ``V*(start)``, logged as ``model/value_start_true`` beside
            ``model/value_start`` (``None``: not logged).
        initial_value: the learner's initial state value (grey on the value map).
        resume_step: continue runs checkpointed at this step: their folders may hold events, and
            those their earlier process logged after the step are purged. ``None`` (default): a
            fresh start.
        overwrite: on a fresh start, empty run folders that already hold events instead of
            refusing them.

    Raises:
        FileExistsError: on a fresh start, if a run folder already holds events and not
            ``overwrite`` — its curves would mix with this run's.
    """

    def __init__(
        self,
        root: str | os.PathLike,
        names: Sequence[str],
        *,
        world=None,
        options=None,
        true_value_start: float | None = None,
        initial_value: float = -1.0,
        resume_step: int | None = None,
        overwrite: bool = False,
    ):
        from torch.utils.tensorboard import SummaryWriter

        root = Path(root)
        names = list(names)
        if len(set(names)) != len(names):
            raise ValueError(f"TensorBoardLogger: run names must be distinct, got {names}")
        if resume_step is not None and int(resume_step) < 0:
            raise ValueError(f"TensorBoardLogger: resume_step={resume_step} must be ≥ 0")
        used = [n for n in names if _has_events(root / n)]
        if used and resume_step is None:
            if not overwrite:
                raise FileExistsError(
                    f"{root} already holds TensorBoard events of {len(used)} of these runs (e.g. "
                    f"{root / used[0]}); a new run would mix its curves with theirs. Log to "
                    f"another folder, resume the run, or overwrite it (overwrite=True; `himit run "
                    f"--force`)"
                )
            for n in used:
                shutil.rmtree(root / n)
        # On resume, TensorBoard drops the events of earlier files at steps ≥ purge_step: what
        # the interrupted process logged after its checkpoint, which this one logs again.
        purge = None if resume_step is None else int(resume_step) + 1
        if used and resume_step is not None:
            _wait_past_existing_event_files([root / n for n in used])
        self.names = names
        self.resume_step = resume_step
        self._writers = [SummaryWriter(str(root / n), purge_step=purge) for n in names]
        self._described: list[set[str]] = [set() for _ in names]
        self._true_value_start = true_value_start
        self._first_goal_logged = [False] * len(names)
        self._renderer = None
        if world is not None:
            from himit_torch.viz.plotting import MapRenderer

            self._renderer = MapRenderer(world, options, initial_value=initial_value)

    # ------------------------------------------------------------------------------- writing
    def _file_writer(self, run: int):
        return self._writers[run]._get_file_writer()

    def scalar(self, run: int, tag: str, value: float, step: int) -> None:
        """Log one scalar; its description (:data:`SCALAR_DESCRIPTIONS`) goes with its first
        value in this process."""
        self.scalars(run, {tag: value}, step)

    def scalars(self, run: int, values: Mapping[str, float], step: int) -> None:
        """Log several scalars of one run at one step, as one event (TensorBoard reads each value
        as its own point, as if logged by :meth:`scalar`; one event instead of one per tag is
        ≈ 3× cheaper to write)."""
        from tensorboard.compat.proto.summary_pb2 import Summary
        from tensorboard.plugins.scalar.metadata import create_summary_metadata

        entries = []
        for tag, value in values.items():
            entry = Summary.Value(tag=tag, simple_value=float(value))
            if tag not in self._described[run]:
                description = SCALAR_DESCRIPTIONS.get(tag, "")
                entry.metadata.CopyFrom(create_summary_metadata(tag, description))
                self._described[run].add(tag)
            entries.append(entry)
        if entries:
            self._file_writer(run).add_summary(Summary(value=entries), int(step))

    def image(self, run: int, tag: str, rgb: np.ndarray, step: int) -> None:
        """Log one ``[H, W, 3]`` uint8 image with its description (:data:`IMAGE_DESCRIPTIONS`)."""
        from tensorboard.compat.proto.summary_pb2 import Summary
        from tensorboard.plugins.image.metadata import create_summary_metadata
        from torch.utils.tensorboard.summary import image

        if isinstance(rgb, np.ndarray) and rgb.dtype == np.uint8 and rgb.ndim == 3:
            # (the pixels image() encodes for uint8 pixels, without its float32 round trip)
            summary = Summary(value=[Summary.Value(tag=tag, image=_png(rgb))])
        else:
            summary = image(tag, rgb, dataformats="HWC")
        description = IMAGE_DESCRIPTIONS.get(tag, "")
        summary.value[0].metadata.CopyFrom(create_summary_metadata(tag, description))
        self._file_writer(run).add_summary(summary, int(step))

    def text(self, run: int, tag: str, text: str, step: int = 0) -> None:
        self._writers[run].add_text(tag, text, step)

    # --------------------------------------------------------------------- what a run logs
    def window(self, learner, index: int) -> None:
        """Scalars of window ``index`` of ``learner.metrics`` (``charts/``, ``planner/``,
        ``mentor/``), the first goal of runs that found it by then, and — when the window ends
        now (``learner.views.t``) — the model's state (``model/``)."""
        m = learner.metrics
        step = int(m.steps[index])
        total = torch.stack(m.goals_in_window[: index + 1]).sum(0).tolist()
        first = learner.views.first_goal_step.tolist()
        now = step == learner.views.t
        if now:
            coverage = learner.views.model_coverage().tolist()
            value_start = learner.views.state_values()[:, learner.start_state].tolist()
        # (each window's [B] records as Python numbers once, not one tensor index per run)
        goals, epsilon, episodes, episode_steps, backups, decisions, term_wins = (
            x[index].tolist()
            for x in (
                m.goals_in_window,
                m.epsilon,
                m.episodes,
                m.mean_episode_steps,
                m.backups,
                m.decisions,
                m.mentor_term_wins,
            )
        )
        for b in range(len(self._writers)):
            values = {
                "charts/goals_in_window": goals[b],
                "charts/goals_total": total[b],
                "charts/epsilon": epsilon[b],
                "charts/episodes": episodes[b],
            }
            mean_steps = float(episode_steps[b])
            if math.isfinite(mean_steps):
                values["charts/steps_per_episode"] = mean_steps
            values["planner/backups"] = backups[b]
            values["planner/decisions"] = decisions[b]
            wins = float(term_wins[b])
            if math.isfinite(wins):
                values["mentor/term_wins"] = wins
            if not self._first_goal_logged[b] and 0 <= first[b] <= step:
                # A first goal before the resume step was logged (and kept) by the earlier process.
                if self.resume_step is None or first[b] > self.resume_step:
                    # (after the window's charts, at its own step: the tags' order as before)
                    self.scalars(b, values, step)
                    values = {}
                    self.scalar(b, "charts/first_goal_step", first[b], first[b])
                self._first_goal_logged[b] = True
            if now:
                values["model/coverage"] = coverage[b]
                values["model/value_start"] = value_start[b]
                if self._true_value_start is not None:
                    values["model/value_start_true"] = self._true_value_start
            self.scalars(b, values, step)

    def maps(
        self,
        learner,
        runs: Sequence[int],
        step: int,
        mentor_visits: Mapping[int, torch.Tensor] | torch.Tensor | None = None,
    ) -> None:
        """Images ``maps/values``, ``maps/greedy_option`` and ``maps/visits`` of ``runs`` now
        (call it during training: TensorBoard's slider then steps through them).
        ``mentor_visits``: ``[S]`` counts for all runs, or ``{run: [S]}``."""
        if self._renderer is None:
            raise ValueError("TensorBoardLogger.maps needs the world (TensorBoardLogger(world=…))")
        runs = list(runs)
        values, visits = learner.views.state_values(), learner.views.visit_counts()
        greedy = dict(zip(runs, learner.views.greedy_options(runs)))  # (the runs drawn only)
        for b in runs:
            name, at = self.names[b], f"after {step:,} steps"
            mentor = mentor_visits.get(b) if isinstance(mentor_visits, Mapping) else mentor_visits
            self.image(
                b,
                "maps/values",
                self._renderer.values(values[b], f"values V(s) {at}\n{name}"),
                step,
            )
            self.image(
                b,
                "maps/greedy_option",
                self._renderer.policy(greedy[b], f"greedy option {at}\n{name}"),
                step,
            )
            title = f"visits up to {step:,} steps\n{name}"
            self.image(b, "maps/visits", self._renderer.visits(visits[b], mentor, title), step)

    def hparams(
        self, hparams: Sequence[Mapping], metrics: Sequence[Mapping[str, float]], step: int
    ) -> None:
        """Per run, its settings (``hparams[b]``: the settings that tell its group apart, never
        the seed) and its final metrics (``metrics[b]``, tags ``hparam/…``). Runs with equal
        settings share a session group named after them, so TensorBoard's HParams dashboard
        shows the seeds of one agent together."""
        from tensorboard.plugins.hparams.plugin_data_pb2 import HParamsPluginData
        from torch.utils.tensorboard.summary import hparams as hparams_summaries

        for b, (hp, metric) in enumerate(zip(hparams, metrics)):
            if "seed" in hp:
                raise ValueError(
                    "TensorBoardLogger.hparams: the seed is not a setting that tells "
                    "groups apart; leave it out (the run's folder names it)"
                )
            hp = {
                k: (v if isinstance(v, (int, float, str, bool)) else str(v))
                for k, v in hp.items()
                if v is not None
            }
            experiment, start, end = hparams_summaries(hp, {k: 0.0 for k in metric})
            # Sessions with one group name form one group (mean, min, max over its seeds).
            data = HParamsPluginData.FromString(start.value[0].metadata.plugin_data.content)
            data.session_start_info.group_name = ", ".join(f"{k}={hp[k]}" for k in sorted(hp))
            start.value[0].metadata.plugin_data.content = data.SerializeToString()
            writer = self._file_writer(b)
            for summary in (experiment, start, end):
                writer.add_summary(summary)
            self.scalars(b, metric, step)

    def flush(self) -> None:
        for w in self._writers:
            w.flush()

    def close(self) -> None:
        for w in self._writers:
            w.close()
