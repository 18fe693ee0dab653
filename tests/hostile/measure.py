"""Time each bad config of tests/hostile/cases.py through the command line, as a user runs it:
wall seconds and peak resident memory of the whole process (`/usr/bin/time`), its status and
error line; and the seconds of the command itself in this process, without Python's start and
imports (the first row, `--help`, is that start alone). Prints a Markdown table
(docs/hostile.md):

    .venv/bin/python -m tests.hostile.measure
"""

from __future__ import annotations

import contextlib
import io
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from harness.cli import main as harness_main
from harness.repo import REPO_ROOT

from tests.hostile.cases import CASES


def measure(config: bytes, files: dict[str, bytes],
            help_only: bool = False) -> tuple[int, float, float, float, str]:
    """Status, wall seconds and peak MB of the process, seconds in this process, and the first
    stderr line of one case."""
    with tempfile.TemporaryDirectory() as tmp:
        directory = Path(tmp)
        for name, data in files.items():
            (directory / name).write_bytes(data)
        (directory / "exp.yaml").write_bytes(config)
        args = (["run", "--help"] if help_only else
                ["run", str(directory / "exp.yaml"), "--dry-run", "--results-dir",
                 str(directory / "r")])
        run = subprocess.run(
            ["/usr/bin/time", "-f", "%e %M", "-o", str(directory / "time"), sys.executable,
             "-m", "harness", *args], capture_output=True, text=True, timeout=600,
            check=False, cwd=REPO_ROOT)
        seconds, kib = (directory / "time").read_text().split()[-2:]
        first = (run.stderr.splitlines() or [""])[0].replace(str(directory) + "/", "")
        start = time.perf_counter()
        with contextlib.redirect_stderr(io.StringIO()), \
                contextlib.redirect_stdout(io.StringIO()), \
                contextlib.suppress(SystemExit):  # --help exits
            harness_main(args)
        inside = time.perf_counter() - start
        return run.returncode, float(seconds), int(kib) / 1024, inside, first


def main() -> None:
    print("| case | kind | status | process s | MB | command s | error line |")
    print("|---|---|---|---|---|---|---|")
    rows = [("`run --help` (Python's start)", "", b"", {}, True),
            *((c.id, c.kind, c.config, c.files, False) for c in CASES)]
    for name, kind, config, files, help_only in rows:
        status, seconds, mb, inside, line = measure(config, files, help_only)
        shown = "" if help_only else line if len(line) <= 100 else line[:97] + "..."
        print(f"| {name} | {kind} | {status} | {seconds:.2f} | {mb:.0f} | {inside:.3f} | "
              f"`{shown}` |", flush=True)


if __name__ == "__main__":
    main()
