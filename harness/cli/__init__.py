"""The command line: `collide-bench COMMAND ARGS...` (also `python -m harness COMMAND`, and the
scripts harness/run.py and harness/compare.py for run and compare).

Each command is a module here with `parser(prog)` and `execute(args) -> exit status`; main()
parses, runs it, and prints any HarnessError as one `error: ...` line with exit status 2
(real bugs keep their traceback).
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from types import ModuleType

from harness.cli.common import EXIT_ERROR, PROG
from harness.errors import HarnessError


def commands() -> dict[str, ModuleType]:
    """The commands by name (imported when asked for: each pulls in what it needs)."""
    from harness.cli import compare, report, run, store, worker

    return {"run": run, "compare": compare, "report": report, "store": store,
            "worker": worker}


def usage() -> str:
    lines = [f"usage: {PROG} COMMAND [ARGS...]", "", "commands:"]
    for name, module in commands().items():
        lines.append(f"  {name:<8} {(module.__doc__ or '').strip().splitlines()[0]}")
    lines.append(f"\n`{PROG} COMMAND --help` says more.")
    return "\n".join(lines) + "\n"


def main(argv: Sequence[str] | None = None) -> int:
    args = list(sys.argv[1:] if argv is None else argv)
    if not args or args[0] in ("-h", "--help"):
        (sys.stdout if args else sys.stderr).write(usage())
        return 0 if args else EXIT_ERROR
    known = commands()
    module = known.get(args[0])
    if module is None:
        sys.stderr.write(f"error: unknown command {args[0]!r}; expected one of: "
                         f"{', '.join(known)} (see {PROG} --help)\n")
        return EXIT_ERROR
    parsed = module.parser(f"{PROG} {args[0]}").parse_args(args[1:])
    try:
        return int(module.execute(parsed))
    except HarnessError as exc:
        sys.stderr.write(f"error: {exc}\n")
        return EXIT_ERROR
