"""env.json: the machine, the tools and the flags a measurement ran with."""

from __future__ import annotations

import datetime
import os
import platform
import socket
import subprocess
import sys
from pathlib import Path

CPUINFO = Path("/proc/cpuinfo")
COMMAND_TIMEOUT_S = 30


def available_cores() -> int:
    """The cores this process may run on (affinity), falling back to the CPU count."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def cpu_model() -> str | None:
    try:
        for line in CPUINFO.read_text().splitlines():
            key, _, value = line.partition(":")
            if key.strip() in ("model name", "Model", "Hardware"):
                return value.strip()
    except OSError:
        pass
    return platform.processor() or None


def command_output(argv: list[str], cwd: Path | None = None) -> str | None:
    """stdout of a command, stripped, or None when it is missing or fails."""
    try:
        done = subprocess.run(argv, cwd=cwd, capture_output=True, text=True,
                              timeout=COMMAND_TIMEOUT_S, check=False)
    except (OSError, subprocess.TimeoutExpired):
        return None
    return done.stdout.strip() if done.returncode == 0 else None


def compiler_info(repo_root: Path, make: str) -> dict[str, str | None]:
    """`make -s print-flags` when the Makefile has that target, else `cc --version`."""
    flags = command_output([make, "-s", "print-flags"], cwd=repo_root)
    version = command_output(["cc", "--version"])
    return {
        "print_flags": flags,
        "cc_version": version.splitlines()[0] if version else None,
    }


def git_info(repo_root: Path) -> dict[str, object]:
    commit = command_output(["git", "rev-parse", "HEAD"], cwd=repo_root)
    status = command_output(["git", "status", "--porcelain", "--untracked-files=no"],
                            cwd=repo_root)
    return {"commit": commit, "dirty": bool(status) if status is not None else None}


def collect(repo_root: Path, make: str = "make", hyperfine: str = "hyperfine") -> dict[str, object]:
    """Everything env.json records."""
    return {
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "hostname": socket.gethostname(),
        "platform": platform.platform(),
        "cpu_model": cpu_model(),
        "cores": available_cores(),
        "cpu_count": os.cpu_count(),
        "compiler": compiler_info(repo_root, make),
        "hyperfine": command_output([hyperfine, "--version"]),
        "git": git_info(repo_root),
        "omp_env": {k: v for k, v in sorted(os.environ.items()) if k.startswith(("OMP_", "GOMP_"))},
        "python": sys.version.split()[0],
    }
