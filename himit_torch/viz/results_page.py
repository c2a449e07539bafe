"""One writer of a study's ``results.md``: its title, the provenance lines (which commit ran
the runs, which command redraws the page, which command reruns them) and the study's own
sections, in that order.

Every study's report writer (the Gymnasium comparison's, discovery's, the puzzle box's)
supplies only its sections; :func:`write_results_page` lays the page out the same way for each:

.. code-block:: text

    # <title>

    <provenance paragraph>

    <provenance paragraph> …
    <the sections' lines, as they are>
"""

from __future__ import annotations

import os
import shlex
from collections.abc import Iterable, Sequence
from dataclasses import asdict
from pathlib import Path

__all__ = [
    "results_page",
    "write_results_page",
    "provenance_line",
    "plot_command",
    "learner_settings_line",
]


def plot_command(run_dir: str | os.PathLike) -> str:
    """The command that redraws the page of ``run_dir``, quoted as a shell reads it, in
    backticks: ```himit plot <run_dir>```."""
    return f"`himit plot {shlex.quote(str(run_dir))}`"


def provenance_line(commits: Sequence[str], source: str, page: str, runs: str) -> str:
    """The page's first provenance sentence: ``Runs recorded at commit `c` <source>; this page:
    <page>; the runs: <runs>``.

    Args:
        commits: the commits that ran the runs (``commits`` in the plural where several).
        source: what follows the commits, as it is (where the commits were read from, e.g.
            `` (from `summary.json`)``; the engines).
        page: how the page was written (e.g. :func:`plot_command`).
        runs: the command (or settings) that reruns the runs, with its own punctuation.
    """
    if not commits:
        raise ValueError("provenance_line: commits is empty; give the commit(s) that ran the runs")
    plural = "s" if len(commits) > 1 else ""
    listed = ", ".join(f"`{c}`" for c in commits)
    return f"Runs recorded at commit{plural} {listed}{source}; this page: {page}; the runs: {runs}"


def results_page(title: str, provenance: Sequence[str], sections: Iterable[Sequence[str]]) -> str:
    """The text of a ``results.md``: ``# title``, each provenance paragraph followed by a blank
    line, then every section's lines as they are (a section ends with its own blank line), the
    lines joined by newlines."""
    if not isinstance(title, str) or not title:
        raise ValueError(f"results_page: title must be a non-empty string, got {title!r:.60}")
    if isinstance(provenance, str):
        raise TypeError("results_page: provenance must be a sequence of paragraphs, not a string")
    lines = [f"# {title}", ""]
    for paragraph in provenance:
        lines += [paragraph, ""]
    for section in sections:
        if isinstance(section, str):
            raise TypeError("results_page: each section must be a sequence of lines, not a string")
        lines += section
    return "\n".join(lines)


def write_results_page(
    run_dir: str | os.PathLike,
    title: str,
    provenance: Sequence[str],
    sections: Iterable[Sequence[str]],
) -> Path:
    """Write ``run_dir/results.md`` (:func:`results_page`); returns its path."""
    path = Path(run_dir) / "results.md"
    path.write_text(results_page(title, provenance, sections))
    return path


def learner_settings_line(config) -> str:
    """A results page's line on ``config``'s learner: the study's preset (if it has one), the
    greedy policy's ties and every learner setting."""
    ties = f"greedy ties `{config.learner.tie_break}`. "
    preset = getattr(config, "preset", None)
    return (
        (
            f"Preset `{preset}` (`himit_torch.learner.presets`), {ties}"
            if preset
            else f"No preset; {ties}"
        )
        + "Learner settings: "
        + ", ".join(f"`{k}={v}`" for k, v in asdict(config.learner).items())
    )
