"""What every command shares: its argument parser's way with errors, the program's name."""

from __future__ import annotations

import argparse
import sys
from typing import NoReturn

EXIT_ERROR = 2
PROG = "collide-bench"


class Parser(argparse.ArgumentParser):
    """argparse that reports a usage error as one `error:` line (exit 2), like the harness."""

    def error(self, message: str) -> NoReturn:
        sys.stderr.write(f"error: {message} (see {self.prog} --help)\n")
        sys.exit(EXIT_ERROR)
