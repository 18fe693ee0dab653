"""The command line: `collide-bench COMMAND ARGS...` (also `python -m harness COMMAND`, and the
scripts harness/run.py and harness/compare.py for run and compare).

Each command is a module (the core's here, a feature's in its package: COMMAND_MODULES) with
`parser(prog)` and `execute(args, hooks) -> exit status`, `hooks` being what the features lend
the core's measuring. main() parses, runs it, and prints any HarnessError, and any OS error a
user can cause (harness.errors.USER_ERRNOS), as one `error: ...` line with exit status 2 (real
bugs keep their traceback). A measuring command also says, in INTERRUPTED (formatted with its
arguments), what a Ctrl-C or SIGTERM keeps: it then ends with that line and status 130.
"""

import importlib
import signal
import sys
import textwrap
from collections.abc import Sequence
from types import ModuleType

from harness import programs
from harness.errors import USER_ERRNOS, HarnessError, os_error_text
from harness.report.parts import ReportFeature
from harness.runner.command import EXIT_ERROR, EXIT_INTERRUPTED, PROG, Hooks

USAGE_WIDTH = 100
# Each command's module: the core's here, a feature's in its own package.
COMMAND_MODULES: dict[str, str] = {
    "run": "harness.cli.run", "compare": "harness.comparison.command",
    "reruns": "harness.reruns.command", "history": "harness.history.command",
    "report": "harness.cli.report", "store": "harness.cli.store", "worker": "harness.cli.worker",
}
COMMANDS: tuple[str, ...] = tuple(COMMAND_MODULES)
# The features the command line lends the core, which imports none of them (light to import:
# what they run is imported when used).
REPORT_FEATURES: tuple[ReportFeature, ...] = (programs.REPORT,)
HOOKS = Hooks(program_runner=programs.start_program)


def command(name: str) -> ModuleType:
    """A command's module, imported when asked for: each pulls in what it needs (run needs
    neither pandas nor matplotlib)."""
    return importlib.import_module(COMMAND_MODULES[name])


def summary(doc: str | None) -> str:
    """A command's docstring's first sentence, whole, however many lines it spans."""
    paragraph = " ".join((doc or "").strip().split("\n\n")[0].split())
    end = paragraph.find(". ")
    return paragraph if end < 0 else paragraph[:end + 1]


def usage() -> str:
    lines = [f"usage: {PROG} COMMAND [ARGS...]", "", "commands:"]
    for name in COMMANDS:
        lines += textwrap.wrap(summary(command(name).__doc__), USAGE_WIDTH,
                               initial_indent=f"  {name:<8} ", subsequent_indent=" " * 11)
    lines.append(f"\n`{PROG} COMMAND --help` says more.")
    return "\n".join(lines) + "\n"


def main(argv: Sequence[str] | None = None) -> int:
    args = list(sys.argv[1:] if argv is None else argv)
    if not args or args[0] in ("-h", "--help"):
        (sys.stdout if args else sys.stderr).write(usage())
        return 0 if args else EXIT_ERROR
    if args[0] not in COMMANDS:
        sys.stderr.write(f"error: unknown command {args[0]!r}; expected one of: "
                         f"{', '.join(COMMANDS)} (see {PROG} --help)\n")
        return EXIT_ERROR
    module = command(args[0])
    parsed = module.parser(f"{PROG} {args[0]}").parse_args(args[1:])
    kept = getattr(module, "INTERRUPTED", None)
    if kept is not None:
        # SIGTERM (a kill, Slurm's time limit) ends it as Ctrl-C does: a KeyboardInterrupt, on
        # which the running cell's processes are killed and the finished cells are kept.
        signal.signal(signal.SIGTERM, signal.default_int_handler)
    try:
        return int(module.execute(parsed, HOOKS))
    except HarnessError as exc:
        sys.stderr.write(f"error: {exc}\n")
        return EXIT_ERROR
    except OSError as exc:  # a full disk, a read-only place, a file where a directory should be
        if exc.errno not in USER_ERRNOS:
            raise
        sys.stderr.write(f"error: {os_error_text(exc)}\n")
        return EXIT_ERROR
    except KeyboardInterrupt:
        if kept is None:
            raise
        sys.stderr.write(f"interrupted: {kept.format(**vars(parsed))}\n")
        return EXIT_INTERRUPTED
