"""``articutool --help`` and every subcommand's help are plain text: no reST or Markdown markup."""

from __future__ import annotations

import argparse
import re

from articutool.cli import build_parser

_MARKUP = re.compile(r"`|:(class|func|meth|mod|attr|ref):|\*\*")


def _parsers(parser: argparse.ArgumentParser, name: str = "articutool"):  # type: ignore[no-untyped-def]
    yield name, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub, p in action.choices.items():
                yield from _parsers(p, f"{name} {sub}")


def test_every_help_text_is_plain_text() -> None:
    seen = 0
    for name, p in _parsers(build_parser()):
        text = p.format_help()
        assert not _MARKUP.search(text), f"{name} --help has markup: {_MARKUP.search(text)}"
        seen += 1
    assert seen > 20  # the top level, every command and their actions
