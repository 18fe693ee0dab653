"""The quick start's experiment (configs/quickstart.yaml, `make quickstart`) measures every
variant the Makefile builds: none is left out to make it quick."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

from harness import repo

CONFIG = repo.REPO_ROOT / "configs" / "quickstart.yaml"


def test_every_variant_has_a_cell(tmp_path: Path) -> None:
    variants = subprocess.run(["make", "-s", "print-variants"], cwd=repo.REPO_ROOT,
                              capture_output=True, text=True, check=True).stdout.split()
    done = subprocess.run([sys.executable, "-m", "harness", "run", str(CONFIG), "--dry-run",
                           "--results-dir", str(tmp_path)], cwd=repo.REPO_ROOT,
                          capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    planned = re.findall(r"^\s+\[\d+/\d+\] (\S+) ", done.stdout, flags=re.MULTILINE)
    assert set(planned) == set(variants)
    # validated against seq, every cell
    assert all("+validate" in line for line in done.stdout.splitlines() if "] " in line
               and not line.lstrip().startswith("excluded"))
