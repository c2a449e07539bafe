"""Every ``--help`` of ``himit`` reads as plain text: the help comes from docstrings and settings'
docs written for Sphinx, and the parser strips their roles and literal markup
(:func:`himit_torch.cli.plain_text`) without changing what the docs render."""

import argparse
import re

import pytest

from himit_torch.cli import build_parser, plain_text
from himit_torch.learner.config import LearnerConfig
from himit_torch.validation import settings_of

#: Sphinx markup that must not reach a terminal.
MARKUP = re.compile(r"``|:(?:py:)?(?:func|meth|class|attr|data|mod|doc|ref|obj|exc|const):")


def _helps(parser: argparse.ArgumentParser | None = None, name: str = "himit") -> list:
    """``(command, its --help)`` of ``himit`` and every subcommand, nested ones included
    (``himit run gymnasium``)."""
    parser = parser or build_parser()
    helps = [(name, parser.format_help())]
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for n, sub in action.choices.items():
                helps += _helps(sub, f"{name} {n}")
    return helps


def test_every_subcommand_is_walked():
    names = [name for name, _ in _helps()]
    assert {"himit run", "himit sweep", "himit info", "himit plot"} <= set(names)
    assert {"himit run exp1", "himit run gymnasium", "himit run puzzlebox"} <= set(names)


@pytest.mark.parametrize(("command", "text"), _helps(), ids=[n for n, _ in _helps()])
def test_help_has_no_sphinx_markup(command, text):
    bad = [line for line in text.splitlines() if MARKUP.search(line)]
    assert not bad, f"{command} --help shows Sphinx markup:\n" + "\n".join(bad)


@pytest.mark.parametrize(
    ("rst", "plain"),
    [
        (":func:`~himit_torch.mentor.policy.exact_mentor_transitions`", "exact_mentor_transitions"),
        (":func:`himit_torch.cli.main`", "himit_torch.cli.main"),
        (":class:`LearnerConfig <himit_torch.LearnerConfig>`", "LearnerConfig"),
        (":py:meth:`with_preset`: set", "with_preset: set"),
        ('``mentor_fade = 20`` or ``"goals"``', 'mentor_fade = 20 or "goals"'),
        ("no markup, 95 %% CIs", "no markup, 95 %% CIs"),
    ],
)
def test_plain_text(rst, plain):
    assert plain_text(rst) == plain


def test_docs_keep_their_markup():
    """The settings' docs themselves are untouched: the reference pages still render them."""
    docs = " ".join(s.info.doc for s in settings_of(LearnerConfig))
    assert "``" in docs
