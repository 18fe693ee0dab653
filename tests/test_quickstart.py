"""The quick start's experiment (configs/quickstart.yaml, `make quickstart`) measures every
variant the Makefile builds but the MPI ones: none is left out to make it quick."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest
from harness import repo

from commands import run_main

CONFIG = repo.REPO_ROOT / "configs" / "quickstart.yaml"


def test_every_variant_has_a_cell(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    variants = subprocess.run(["make", "-s", "print-variants"], cwd=repo.REPO_ROOT,
                              capture_output=True, text=True, check=True).stdout.split()
    # but the MPI variants (the Makefile's rule: their file includes <mpi.h>): they need Open
    # MPI, which the quick start does not install, and run under mpirun (docs/mpi.md)
    variants = [v for v in variants if "#include <mpi.h>" not in
                (repo.REPO_ROOT / "variants" / f"{v}.c").read_text(encoding="utf-8")]
    status = run_main([str(CONFIG), "--dry-run", "--results-dir", str(tmp_path)])
    printed = capsys.readouterr()
    assert status == 0, printed.err
    planned = re.findall(r"^\s+\[\d+/\d+\] (\S+) ", printed.out, flags=re.MULTILINE)
    assert set(planned) == set(variants)
    # validated against seq, every cell
    assert all("+validate" in line for line in printed.out.splitlines() if "] " in line
               and not line.lstrip().startswith("excluded"))
