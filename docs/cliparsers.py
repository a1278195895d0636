"""The programs' own argparse parsers, with their help texts escaped for reStructuredText.

sphinx-argparse reads help and description texts as reStructuredText, where ``|x|`` is a
substitution and ``*`` starts emphasis; the terminal's ``--help`` shows them as plain text. The
parsers are built by the programs' own functions, so the reference cannot drift from ``--help``.
"""

from __future__ import annotations

import argparse
import re

_SPECIAL = re.compile(r"([|*`_\\])")


def _escape(text: str | None) -> str | None:
    return None if text is None else _SPECIAL.sub(r"\\\1", text)


def _escaped(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """``parser`` (and its subcommands' parsers) with every help and description text escaped."""
    parser.description = _escape(parser.description)
    parser.epilog = _escape(parser.epilog)
    for action in parser._actions:  # argparse keeps no public list of a parser's actions
        if action.help not in (None, argparse.SUPPRESS):
            action.help = _escape(action.help)
        if isinstance(action, argparse._SubParsersAction):
            for choice in action._choices_actions:
                choice.help = _escape(choice.help)
            for sub in set(action.choices.values()):
                _escaped(sub)
    return parser


def qsid() -> argparse.ArgumentParser:
    """The ``qsid`` parser with every command's options."""
    from app.cli import build_parser

    return _escaped(build_parser())


def qsid_dashboard() -> argparse.ArgumentParser:
    """The ``qsid-dashboard`` parser."""
    from app.dashboard.options import parser

    return _escaped(parser())
