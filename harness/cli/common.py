"""What every command shares: its argument parser's way with errors, the program's name, how
a measuring command ends when stopped."""

from __future__ import annotations

import argparse
import signal
import sys
from typing import NoReturn

EXIT_ERROR = 2
EXIT_INTERRUPTED = 130  # what a shell reports for a process Ctrl-C ended
PROG = "collide-bench"


class Parser(argparse.ArgumentParser):
    """argparse that reports a usage error as one `error:` line (exit 2), like the harness."""

    def error(self, message: str) -> NoReturn:
        sys.stderr.write(f"error: {message} (see {self.prog} --help)\n")
        sys.exit(EXIT_ERROR)


def interrupt_on_sigterm() -> None:
    """SIGTERM (a kill, Slurm's time limit) ends the command as Ctrl-C does: a KeyboardInterrupt,
    on which the running cell's processes are killed and the finished cells are kept."""
    signal.signal(signal.SIGTERM, _terminate)


def _terminate(signum: int, frame: object) -> None:
    raise KeyboardInterrupt
