"""``articutool --help`` and every subcommand's help are plain text: no reST or Markdown markup."""

from __future__ import annotations

import argparse
import ast
import re
import subprocess
import sys

import pytest

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


def _parsers_choices() -> list[str]:
    """The top-level commands."""
    return [name.split()[1] for name, _ in _parsers(build_parser()) if name.count(" ") == 1]


# What a command's --help and a mistyped argument must not import: the numerics, the data
# models and the spec (a user's typo is answered at once, before anything heavy).
_HEAVY = ("numpy", "pydantic", "articutool.spec", "scipy", "mujoco", "pinocchio")
_PROBE = ("import sys\nfrom articutool.cli import main\n"
          "code = main(sys.argv[1:])\n"
          f"print(code, sorted(m for m in {_HEAVY!r} if m in sys.modules))\n")


def _heavy_imports(*args: str) -> tuple[int, list[str]]:
    out = subprocess.run([sys.executable, "-c", _PROBE, *args], capture_output=True,
                         text=True, timeout=120, check=True).stdout.split("\n")[-2]
    code, mods = out.split(" ", 1)
    return int(code), ast.literal_eval(mods)


@pytest.mark.parametrize("command", sorted(set(_parsers_choices()) - {"experiment"}))
def test_a_commands_help_imports_nothing_heavy(command: str) -> None:
    # the experiments' options come from their registry, which holds their models
    assert _heavy_imports(command, "--help") == (0, [])


@pytest.mark.parametrize("args", [("demo", "--seed", "-1"), ("sim", "--duration", "-1"),
                                  ("tool", "--bogus"), ("bench", "tasks", "--seed", "-1",
                                                        "--out", "t.json")])
def test_a_mistyped_argument_is_refused_before_anything_heavy(args: tuple[str, ...]) -> None:
    assert _heavy_imports(*args) == (2, [])
