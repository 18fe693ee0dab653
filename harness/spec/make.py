"""Building binaries with make: the one place the spec runs a build (harness.spec.variants asks
it for the binaries it describes; the runner for those a run measures). Whoever only reads
results never imports it (pyproject.toml's import-linter contracts)."""

from __future__ import annotations

import subprocess
from collections.abc import Iterable, Sequence
from pathlib import Path

from harness.errors import HarnessError


def make_binaries(repo_root: Path, binaries: Iterable[Path], make: str = "make",
                  capture: bool = False, extra: Sequence[str] = ()) -> None:
    """One `make -s [EXTRA] build/a build/b ...` call (nothing when the list is empty); a
    failure is a HarnessError. With `capture`, make's output goes into the error only."""
    targets = [str(b.relative_to(repo_root)) for b in binaries]
    if not targets:
        return
    done = _make(repo_root, make, ["-s", *extra, *targets], capture)
    if done.returncode != 0:
        detail = f": {' '.join(done.stderr.split())[-500:]}" if capture and done.stderr else ""
        raise HarnessError(f"make -s {' '.join([*extra, *targets])} failed with exit status "
                           f"{done.returncode}{detail}")


def has_rules(repo_root: Path, binaries: Iterable[Path], make: str = "make") -> bool:
    """Whether the Makefile in `repo_root` can make every one of `binaries`: `make -n` (a dry
    run, nothing built) finds a rule for each and for what each is made of."""
    targets = [str(b.relative_to(repo_root)) for b in binaries]
    return _make(repo_root, make, ["-n", "-s", *targets], capture=True).returncode == 0


def _make(repo_root: Path, make: str, args: Sequence[str],
          capture: bool) -> subprocess.CompletedProcess[str]:
    try:
        return subprocess.run([make, *args], cwd=repo_root, check=False, text=True,
                              errors="replace", stdin=subprocess.DEVNULL,
                              capture_output=capture)
    except OSError as exc:
        raise HarnessError(f"cannot run {make}: {exc.strerror}") from None
