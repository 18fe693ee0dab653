"""env.json: everything a measuring run records about where it ran: the machine
(harness.measure.machine) plus what can change between runs on it (clock, governor, kernel, C
library, compiler flags, libgomp, OMP_*, hyperfine, git, load). Only called when a run
measures."""

from __future__ import annotations

import contextlib
import datetime
import functools
import os
import platform
import socket
import sys
from pathlib import Path

import psutil

from harness.measure.machine import (
    CPU_SYS,
    available_cores,
    command_output,
    container,
    load,
    machine,
    make_compiler,
    print_flags,
    read_text,
)
from harness.repo import DEFAULT_REPORT_DIR, DEFAULT_RESULTS_DIR, PUBLISHED_DIR


def clock() -> dict[str, object]:
    """Current and maximum clock (MHz), governor and boost where the kernel exposes them."""
    freq = None
    with contextlib.suppress(OSError, NotImplementedError):
        freq = psutil.cpu_freq()
    boost = read_text(CPU_SYS / "cpufreq" / "boost")
    no_turbo = read_text(CPU_SYS / "intel_pstate" / "no_turbo")
    return {
        "current_mhz": freq.current if freq else None,
        "max_mhz": freq.max if freq and freq.max else None,
        "governor": read_text(CPU_SYS / "cpu0" / "cpufreq" / "scaling_governor"),
        "boost": (boost == "1") if boost is not None else
        ((no_turbo == "0") if no_turbo is not None else None),
    }


def libc() -> dict[str, object]:
    name, version = platform.libc_ver()
    ldd = command_output(["ldd", "--version"])
    return {"name": name or None, "version": version or None,
            "ldd": ldd.splitlines()[0] if ldd else None}


def libgomp(compiler: str) -> dict[str, str | None]:
    """The libgomp the compiler links (its path) and, on Debian, the package's version."""
    path = command_output([compiler, "-print-file-name=libgomp.so"])
    package = command_output(["dpkg-query", "-W", "-f=${Version}", "libgomp1"])
    return {"path": os.path.realpath(path) if path and os.sep in path else path,
            "package_version": package}


def compiler_info(repo_root: Path, make: str) -> dict[str, str | None]:
    """`make -s print-flags` (the compiler make uses and its flags) and that compiler's version."""
    flags = print_flags(repo_root, make)
    version = command_output([make_compiler(repo_root, make), "--version"])
    return {
        "print_flags": flags,
        "cc_version": version.splitlines()[0] if version else None,
    }


GENERATED_PATHS = (DEFAULT_RESULTS_DIR.name, DEFAULT_REPORT_DIR.name, PUBLISHED_DIR.name)


def git_info(repo_root: Path) -> dict[str, object]:
    commit = command_output(["git", "rev-parse", "HEAD"], cwd=repo_root)
    # results/, report/ and published/ are what measuring writes: a run's own output must not
    # make the sources it measured look modified.
    status = command_output(["git", "status", "--porcelain", "--untracked-files=no", "--", ".",
                             *(f":!{path}" for path in GENERATED_PATHS)], cwd=repo_root)
    return {"commit": commit, "dirty": bool(status) if status is not None else None}


@functools.cache
def git_commit(repo_root: Path) -> str | None:
    """The commit measuring now, with "-dirty" when tracked files differ from it."""
    info = git_info(repo_root)
    if info["commit"] is None:
        return None
    return f"{info['commit']}{'-dirty' if info['dirty'] else ''}"


def py_cpuinfo() -> dict[str, object]:
    """What py-cpuinfo adds to /proc/cpuinfo: advertised clock, cache sizes (slow; see above)."""
    return dict(_py_cpuinfo())


@functools.cache
def _py_cpuinfo() -> tuple[tuple[str, object], ...]:
    # Once per process: the probe starts an interpreter of its own (about a CPU second), and
    # the CPU it describes does not change while a process measures one config after another.
    try:
        import cpuinfo
        info = cpuinfo.get_cpu_info()
    except Exception:
        return ()
    keys = ("brand_raw", "hz_advertised_friendly", "l2_cache_size", "l3_cache_size", "arch")
    return tuple((k, info.get(k)) for k in keys)


def collect(repo_root: Path, make: str = "make", hyperfine: str = "hyperfine") -> dict[str, object]:
    described = machine(repo_root, make)
    compiler = make_compiler(repo_root, make)
    return {
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "hostname": socket.gethostname(),
        "platform": platform.platform(),
        "kernel": platform.release(),
        "machine_id": described["machine_id"],
        "machine": described,
        "cpu_model": described["model_name"],
        "cpuinfo": py_cpuinfo(),
        "clock": clock(),
        "cores": available_cores(),
        "cpu_count": os.cpu_count(),
        "container": container(),
        "libc": libc(),
        "compiler": compiler_info(repo_root, make),
        "libgomp": libgomp(compiler),
        "hyperfine": command_output([hyperfine, "--version"]),
        "git": git_info(repo_root),
        "omp_env": {k: v for k, v in sorted(os.environ.items()) if k.startswith(("OMP_", "GOMP_"))},
        "python": sys.version.split()[0],
        "load_before": load(),
    }
