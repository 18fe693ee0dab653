"""Time each bad config of tests/hostile/cases.py through the command line, as a user runs it:
wall seconds and peak resident memory of the whole process (`/usr/bin/time`), its status and
error line. Prints a Markdown table (docs/hostile.md):

    .venv/bin/python -m tests.hostile.measure
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
from pathlib import Path

from harness.repo import REPO_ROOT

from tests.hostile.cases import CASES


def measure(case_id: str, config: bytes, files: dict[str, bytes]) -> tuple[int, float, float, str]:
    """Status, wall seconds, peak MB and the first stderr line of one case."""
    with tempfile.TemporaryDirectory() as tmp:
        directory = Path(tmp)
        for name, data in files.items():
            (directory / name).write_bytes(data)
        (directory / "exp.yaml").write_bytes(config)
        run = subprocess.run(
            ["/usr/bin/time", "-f", "%e %M", "-o", str(directory / "time"), sys.executable,
             str(REPO_ROOT / "harness" / "run.py"), str(directory / "exp.yaml"), "--dry-run",
             "--results-dir", str(directory / "r")],
            capture_output=True, text=True, timeout=600, check=False)
        seconds, kib = (directory / "time").read_text().split()[-2:]
        first = (run.stderr.splitlines() or [""])[0].replace(str(directory) + "/", "")
        return run.returncode, float(seconds), int(kib) / 1024, first


def main() -> None:
    print("| case | kind | status | s | MB | error line |")
    print("|---|---|---|---|---|---|")
    for case in CASES:
        status, seconds, mb, line = measure(case.id, case.config, case.files)
        shown = line if len(line) <= 110 else line[:107] + "..."
        print(f"| {case.id} | {case.kind} | {status} | {seconds:.2f} | {mb:.0f} | "
              f"`{shown}` |", flush=True)


if __name__ == "__main__":
    main()
