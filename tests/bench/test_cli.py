"""Tests of bench/cli.py: every command's and benchmark's help is written as argparse formats it."""

import argparse

from livedic.bench.cli import build_parser


def _parsers(parser):
    yield parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for child in action.choices.values():
                yield from _parsers(child)


def test_every_help_text_formats():
    # a bare "%" in a help string is a format directive: "1 % stretch" printed the action's whole dict
    parsers = list(_parsers(build_parser()))
    assert len(parsers) > 20
    for parser in parsers:
        text = parser.format_help()
        assert "option_strings" not in text and "%%" not in text, parser.prog
