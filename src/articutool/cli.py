"""The articutool command line: one parser whose subcommands come from the subsystems.

Exit codes everywhere: 0 success, 1 the job ran and said no (e.g. infeasible), 2 bad input,
3 internal error.
Subsystems contribute subcommands through an ``add_commands(subparsers)`` function in the
modules listed in ``_COMMAND_MODULES``. Building the parser imports neither numpy nor pydantic
nor the spec: each handler imports its heavy dependencies once its arguments are checked, so
``articutool --help`` and a mistyped option are answered at once.
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import sys
import traceback
from collections.abc import Sequence
from typing import Any

from articutool.cli_support import add_spec_option, spec_from_args

__all__ = ["main"]

DESCRIPTION = ("Robot-assisted feeding with a decoupled 2-DOF active wrist: the wrist's onboard\n"
               "loop, the tool-PC link, planning and verification, the physics world, the\n"
               "feeding tree and the thesis' experiments.")
EPILOG = ("Exit codes: 0 success, 1 the job ran and said no (e.g. infeasible), 2 bad input,\n"
          "3 internal error. 'articutool COMMAND --help' describes each command.")

_COMMAND_MODULES: tuple[str, ...] = (
    "articutool.verify.cli",
    "articutool.onboard",
    "articutool.link.cli",
    "articutool.ros2.cli",
    "articutool.sim.demo",
    "articutool.sim.cli",
    "articutool.meal.cli",
    "articutool.bench.cli",
    "articutool.viewer.cli",
    "articutool.experiments.cli",
)

# The errors that mean bad input (exit 2), by the module that defines each. A module not yet
# imported cannot have raised its error, so none is imported only to be caught.
_BAD_INPUT_ERRORS: tuple[tuple[str, str], ...] = (
    ("articutool.cli_support", "UsageError"),
    ("articutool.spec", "SpecError"),
    ("articutool.trajectory", "TrajectoryError"),
    ("articutool.datafile", "ResultsError"),
)


def _is_bad_input(err: BaseException) -> bool:
    """Whether ``err`` is one of :data:`_BAD_INPUT_ERRORS`."""
    return any(isinstance(err, getattr(sys.modules[mod], name))
               for mod, name in _BAD_INPUT_ERRORS if mod in sys.modules)


def _cmd_info(args: argparse.Namespace) -> int:
    spec = spec_from_args(args)
    if args.json:
        print(json.dumps(spec.model_dump(mode="json"), indent=1))
        return 0
    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table

    console = Console()
    w = spec.wrist
    console.print(f"[bold]Articutool hardware spec[/] (version {spec.version})")
    t = Table(title=escape("Wrist (joint order [pitch, roll])"))  # [..] is rich markup
    for col in ("item", "value"):
        t.add_column(col)
    t.add_row("pitch limits (rad)", f"[{w.pitch_limits[0]:.4f}, {w.pitch_limits[1]:.4f}]")
    t.add_row("roll limits (rad)", f"[{w.roll_limits[0]:.4f}, {w.roll_limits[1]:.4f}]")
    t.add_row("roll net-turn budget", f"±{w.roll_turn_budget:g} turns")
    t.add_row("max joint velocity (rad/s)", ", ".join(f"{v:g}" for v in w.max_velocity))
    t.add_row("motor no-load speed (rad/s)", f"{w.motor_max_velocity:g}")
    t.add_row("loop rate (Hz)", f"{w.loop_rate_hz:g}")
    t.add_row("F0 mount xyz / rpy", f"{list(w.mount_xyz)} / {[round(a, 4) for a in w.mount_rpy]}")
    for name, u in spec.utensils.items():
        t.add_row(f"utensil {name} tip (x, z)", f"({u.tip_x:g}, {u.tip_z:g})")
    console.print(t)
    a = Table(title=f"Arm {spec.arm.model}")
    for col in ("joint", "lower", "upper", "max vel", "max acc", "effort"):
        a.add_column(col)
    for j in spec.arm.joints:
        a.add_row(j.name, f"{j.lower:.4f}", f"{j.upper:.4f}", f"{j.max_velocity:g}",
                  f"{j.max_acceleration:g}", f"{j.effort:g}")
    console.print(a)
    for name, q in spec.arm.configurations.items():
        console.print(f"  {name}: {[round(x, 5) for x in q]}")
    for name, pose in spec.arm.poses.items():
        console.print(f"  {name} (pose): p={list(pose.position)} "
                      f"q_wxyz={list(pose.orientation_wxyz)}")
    c = spec.controller
    console.print(f"controller: kp={c.kp} ki={c.ki} kd={c.kd} clamp={c.integral_clamp} "
                  f"deadband={c.deadband} rcond={c.pinv_rcond}")
    f = spec.filter
    console.print(f"filter: gain_acc={f.gain_acc} bias_alpha={f.bias_alpha} "
                  f"adaptive_gain={f.adaptive_gain} bias_estimation={f.bias_estimation}")
    return 0


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The argument parser: every command, or with ``command`` only the command modules up
    to the one that registers it (what parsing that command's arguments needs: the
    experiments' registry is not imported to answer ``articutool sim --help``)."""
    parser = argparse.ArgumentParser(
        prog="articutool", description=DESCRIPTION, epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    p = sub.add_parser("info", help="print the hardware spec")
    add_spec_option(p)
    p.add_argument("--json", action="store_true", help="print the spec as JSON")
    p.set_defaults(func=_cmd_info)
    for mod in _COMMAND_MODULES:
        if command in sub.choices:
            break
        importlib.import_module(mod).add_commands(sub)
    return parser


class _StdoutError(Exception):
    """Standard output cannot be written (a full disk, ``> /dev/full``, a closed file)."""


class _GuardedStdout:
    """``sys.stdout`` whose write failures raise :class:`_StdoutError` (a broken pipe stays
    ``BrokenPipeError``), so they are told apart from a bug's OSError."""

    def __init__(self, stream: Any) -> None:
        self._stream = stream

    def write(self, text: str) -> int:
        try:
            return self._stream.write(text)
        except BrokenPipeError:
            raise
        except OSError as err:
            raise _StdoutError(err.strerror or str(err)) from None

    def flush(self) -> None:
        try:
            self._stream.flush()
        except BrokenPipeError:
            raise
        except OSError as err:
            raise _StdoutError(err.strerror or str(err)) from None

    def __getattr__(self, name: str) -> Any:
        return getattr(self._stream, name)


def _silence_stdout() -> None:
    """Point stdout at /dev/null, so the interpreter's own flush at exit does not fail again
    on what is still buffered."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.__stdout__.fileno())
        os.close(devnull)
    except (OSError, AttributeError, ValueError):
        pass


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``articutool``; returns the exit code."""
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser(argv[0] if argv and not argv[0].startswith("-") else None)
    try:
        args = parser.parse_args(argv)
    except SystemExit as done:  # argparse refused the arguments (2) or printed --help (0)
        return done.code if isinstance(done.code, int) else 2
    real_stdout = sys.stdout
    sys.stdout = _GuardedStdout(real_stdout)  # type: ignore[assignment]
    try:
        code = int(args.func(args))
        sys.stdout.flush()
        return code
    except _StdoutError as err:
        print(f"error: cannot write to standard output: {err}", file=sys.stderr)
        _silence_stdout()
        return 2
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:  # output piped into e.g. `head`
        _silence_stdout()
        return 0
    except Exception as err:
        if _is_bad_input(err):
            print(f"error: {err}", file=sys.stderr)
            return 2
        # a bug, not bad input: keep it distinguishable from exit 1 ("no")
        traceback.print_exc()
        print("error: internal error (please report it with the traceback above)",
              file=sys.stderr)
        return 3
    finally:
        sys.stdout = real_stdout


if __name__ == "__main__":
    # ``python -m articutool.cli``: the subcommands' exceptions live in cli_support, so this
    # copy of the module (as ``__main__``) catches them as ``articutool.cli`` would.
    sys.exit(main())
