"""The ``ceamcl`` command line: a thin layer over the library.

Each subcommand lives in its own module of this package with a ``register(subparsers)``
function that adds its parser and sets ``run(args, console) -> exit code`` as its default.
"""

from __future__ import annotations

import argparse
import os
import sys
import warnings
from collections.abc import Sequence
from importlib import import_module
from typing import NoReturn

from rich.console import Console

from ceamcl import __version__, budget
from ceamcl.budget import Budget, default_memory_bytes, format_bytes, parse_bytes
from ceamcl.cli import interrupt
from ceamcl.errors import CeamclError, InputWarning, RunWarning
from ceamcl.io import created

#: Subcommand modules, in the order ``ceamcl --help`` lists them.
COMMAND_MODULES: tuple[str, ...] = (
    "demo",
    "world",
    "soak",
    "bench",
    "experiment",
    "run",
    "map_from_log",
    "evaluate_log",
    "node",
    "play",
    "warm_up",
)


class DefaultsFormatter(argparse.HelpFormatter):
    """Help that shows each option's default, except where there is none to show (None,
    False) or the help text already states it."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ""
        default = action.default
        if (
            not action.option_strings
            or action.nargs == 0  # flags: their default is the flag's absence
            # identity, not equality: a default of 0 is shown, not taken for False
            or default is None
            or default is False
            or default is argparse.SUPPRESS
            or "default" in text
            or text == argparse.SUPPRESS
            or isinstance(action, argparse._HelpAction | argparse._VersionAction)
        ):
            return action.help
        shown = " ".join(map(str, default)) if isinstance(default, list | tuple) else "%(default)s"
        return f"{text} (default: {shown})" if text else f"default: {shown}"


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line (and a pointer to ``--help``), not the
    whole usage block."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message}\n(see '{self.prog} --help')\n")


def _memory_budget(text: str) -> Budget:
    try:
        return Budget(parse_bytes(text))
    except CeamclError as exc:
        raise argparse.ArgumentTypeError(str(exc).removeprefix("memory-budget: ")) from None


def _leaf_parsers(parser: argparse.ArgumentParser) -> list[argparse.ArgumentParser]:
    """The parsers of the commands that run (``run``, ``experiment table1``, ...)."""
    subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    if not subs:
        return [parser]
    parser.formatter_class = DefaultsFormatter
    return [leaf for a in subs for p in a.choices.values() for leaf in _leaf_parsers(p)]


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="ceamcl",
        description="Coevolution-based adaptive Monte Carlo localisation and its baselines.",
        formatter_class=DefaultsFormatter,
    )
    parser.add_argument("--version", action="version", version=f"ceamcl {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    for name in COMMAND_MODULES:
        import_module(f"ceamcl.cli.{name}").register(sub)
    for command in _leaf_parsers(parser):
        command.formatter_class = DefaultsFormatter
        command.add_argument(
            "--memory-budget",
            type=_memory_budget,
            default=None,
            metavar="SIZE",
            help="refuse inputs that would need more memory than this, e.g. 16GiB "
            f"(default: {format_bytes(default_memory_bytes())}, a quarter of this machine's "
            "memory; docs/robustness.md)",
        )
    return parser


def _show_warning(
    message: Warning | str, category: type[Warning], *_: object, **__: object
) -> None:
    if issubclass(category, InputWarning | RunWarning):
        print(f"ceamcl: warning: {message}", file=sys.stderr)
    else:
        _default_showwarning(message, category, *_, **__)  # type: ignore[arg-type]


_default_showwarning = warnings.showwarning


#: Width of the console output when it goes to a pipe or a file (Rich's default is 80).
CONSOLE_COLUMNS = 100


#: The commands that start ROS 2 and pass what follows ``--ros-args`` to it.
ROS_COMMANDS = ("node", "play")


def _stopped(exc: KeyboardInterrupt) -> int:
    """One line for Ctrl-C (exit 130) or SIGTERM (:class:`interrupt.Terminated`, exit 143)."""
    if isinstance(exc, interrupt.Terminated):
        print("ceamcl: terminated", file=sys.stderr)
        return 143
    print("ceamcl: interrupted", file=sys.stderr)
    return 130


def main(argv: Sequence[str] | None = None) -> int:
    """Run one command. Bad input, or a file that cannot be read or written: one line on
    stderr, exit 2. Ctrl-C: one line, exit 130;
    SIGTERM: one line, exit 143. Either way an output folder the command created is removed
    again."""
    # building the parser imports every command (about 2 s): a signal then ended the process
    # with Python's traceback (Ctrl-C) or without a word (SIGTERM)
    try:
        with interrupt.during_setup():
            parser = build_parser()
    except KeyboardInterrupt as exc:  # Terminated too
        return _stopped(exc)
    words = list(sys.argv[1:] if argv is None else argv)
    # ROS's own arguments (``ceamcl node --ros-args -p name:=value``) pass through untouched,
    # for the commands that start ROS; any other command refuses them as unknown arguments
    command = next((w for w in words if not w.startswith("-")), None)
    takes_ros = command in ROS_COMMANDS and "--ros-args" in words
    cut = words.index("--ros-args") if takes_ros else len(words)
    args = parser.parse_args(words[:cut])
    args.ros_args = words[cut:]
    console = Console(stderr=False)
    if not console.is_terminal and "COLUMNS" not in os.environ:
        console.width = CONSOLE_COLUMNS  # a pipe or a file: tables of 100 columns, not 80
    limits = args.memory_budget or Budget.default()
    ok = False
    created.forget()  # folders a library call made earlier in this process are not ours
    try:
        own_ctrl_c = getattr(args, "handles_ctrl_c", False)
        with interrupt.guard(not own_ctrl_c), budget.use(limits), warnings.catch_warnings():
            warnings.simplefilter("always", InputWarning)
            warnings.showwarning = _show_warning
            code: int = args.run(args, console)
            if interrupt.pending():
                # Ctrl-C landed where Python drops exceptions (a finaliser, a garbage
                # collector's callback) or in the compiler, where it waits, and the command
                # returned before it was raised again: it was interrupted all the same
                raise interrupt.consume()
        ok = True  # a command that returns has written its results (soak exits 1 on a finding)
    except CeamclError as exc:
        print(f"ceamcl: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        if exc.filename is None:  # not about a file: a fault, with its traceback
            raise
        # a file that could not be read or written (a permission, a folder where a file
        # goes, a full disk) where no command turned it into its own message
        where = repr(str(exc.filename))
        if exc.filename2 is not None:
            where += f" -> {str(exc.filename2)!r}"
        print(f"ceamcl: error: {where}: {exc.strerror or exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:  # Terminated too
        return _stopped(exc)
    except MemoryError:
        print(
            f"ceamcl: error: out of memory ({limits.describe()}); an input size escaped the "
            "budget checks, please report it",
            file=sys.stderr,
        )
        return 3
    finally:
        if ok:
            created.forget()
        else:
            created.remove_created()
    return code


if __name__ == "__main__":
    sys.exit(main())
