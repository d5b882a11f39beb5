"""`courtside --help` and every subcommand's help read as a user's manual (issue 30): each command listed with a
one-line summary, every option of every subcommand explained, no internal jargon ("issue 11") and no paths of
this build machine (/work/...); `demo --help` is a description, not the module's comment.

The parsers are taken from the commands themselves (each builds its parser inside its main): argparse's
`parse_known_args` is intercepted at the first parser that offers --help, so no command runs. Subcommands of a
command (``camera synth``) are walked; the gateway's ``export`` / ``new-secret`` are parsers of their own,
reached by their first word."""
from __future__ import annotations

import argparse
import contextlib
import io
import re

import pytest

from gateway.cli import SUMMARIES, available_commands, main as courtside

JARGON = re.compile(r"\bissues? \d+|/work/")
CODE_COMMENT = re.compile(r"entry points?\b|pyproject|python -m")  # a module docstring used as the description
FIRST_WORDS = {"gateway": [[], ["export"], ["new-secret"]]}  # argv before --help reaching each parser


class _Caught(Exception):
    def __init__(self, parser: argparse.ArgumentParser) -> None:
        self.parser = parser


def _parser_of(command: str, first_words: list[str], monkeypatch: pytest.MonkeyPatch) -> argparse.ArgumentParser:
    parse_known_args = argparse.ArgumentParser.parse_known_args

    def catch(self, args=None, namespace=None):
        if not self.add_help:  # a pre-parser picking one option before the real parser is built (evaluate)
            return parse_known_args(self, args, namespace)
        raise _Caught(self)

    monkeypatch.setattr(argparse.ArgumentParser, "parse_known_args", catch)
    try:
        available_commands()[command].load()(first_words + ["--help"])
    except _Caught as caught:
        return caught.parser
    raise AssertionError(f"courtside {command} parsed no arguments")


def _parsers(parser: argparse.ArgumentParser, name: str) -> list[tuple[str, argparse.ArgumentParser]]:
    """The parser and its subcommands' parsers, named as typed."""
    found = [(name, parser)]
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub, sub_parser in action.choices.items():
                found += _parsers(sub_parser, f"{name} {sub}")
    return found


def _help_problems(name: str, parser: argparse.ArgumentParser) -> list[str]:
    problems = []
    for action in parser._actions:
        if isinstance(action, (argparse._HelpAction, argparse._SubParsersAction)):
            continue
        what = f"{name} {'/'.join(action.option_strings) or action.dest}"
        if not (action.help or "").strip():
            problems.append(f"{what}: no help")
        elif JARGON.search(action.help):
            problems.append(f"{what}: jargon in {action.help!r}")
    for text in (parser.description or "", parser.epilog or ""):
        if JARGON.search(text):
            problems.append(f"{name}: jargon in its description: {JARGON.search(text)[0]!r}")
    return problems


@pytest.mark.parametrize("command", sorted(available_commands()))
def test_every_option_of_every_subcommand_has_help_without_jargon(command, monkeypatch):
    problems = []
    for first_words in FIRST_WORDS.get(command, [[]]):
        parser = _parser_of(command, first_words, monkeypatch)
        assert parser.description and not CODE_COMMENT.search(parser.description), \
            f"courtside {command}: no description, or a module comment: {parser.description!r}"
        for name, sub in _parsers(parser, " ".join(["courtside", command, *first_words])):
            problems += _help_problems(name, sub)
    assert not problems, "\n".join(problems)


def test_courtside_help_lists_every_command_with_a_summary():
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert courtside(["--help"]) == 0
    assert set(SUMMARIES) == set(available_commands())  # a new command needs its line
    listed = {line.split()[0]: line for line in out.getvalue().splitlines() if line.startswith("  ")}
    assert set(listed) == set(available_commands())
    for name, line in listed.items():
        assert SUMMARIES[name] in line and not JARGON.search(line)


def test_help_shows_the_defaults(monkeypatch, capsys):
    """Options with a value say it: in their own words or argparse's "(default: ...)"."""
    parser = _parser_of("camera", [], monkeypatch)
    synth = dict(_parsers(parser, "camera"))["camera synth"]
    text = synth.format_help()
    assert "(default: court.mp4)" in text and "(default: 30.0)" in text
    gateway = _parser_of("gateway", [], monkeypatch).format_help()
    assert "refused (default 32)" in " ".join(gateway.split()) and "(default: None)" not in gateway
