"""env.json: everything a measuring run records about where it ran: the machine
(harness.measure.machine) plus what can change between runs on it (clock, governor, kernel, C
library, compiler flags, libgomp, OMP_*, hyperfine, git, load). Only called when a run
measures."""

import contextlib
import functools
import os
import platform
import socket
import sys
from pathlib import Path

import psutil

from harness.measure import machine
from harness.measure.machine import CPU_SYS, command_output, read_text
from harness.repo import DEFAULT_REPORT_DIR, DEFAULT_RESULTS_DIR, PUBLISHED_DIR
from harness.store.records import now_iso

# What measuring writes: a run's own output must not make the sources it measured look
# modified.
GENERATED_PATHS = (DEFAULT_RESULTS_DIR.name, DEFAULT_REPORT_DIR.name, PUBLISHED_DIR.name)
PY_CPUINFO_KEYS = ("brand_raw", "hz_advertised_friendly", "l2_cache_size", "l3_cache_size",
                   "arch")


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


def _first_line(text: str | None) -> str | None:
    return text.splitlines()[0] if text else None


def git_info(repo_root: Path) -> dict[str, object]:
    commit = command_output(["git", "rev-parse", "HEAD"], cwd=repo_root)
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


@functools.cache
def _py_cpuinfo() -> tuple[tuple[str, object], ...]:
    """What py-cpuinfo adds to /proc/cpuinfo: advertised clock, cache sizes. Once per process:
    the probe starts an interpreter of its own (about a CPU second), and the CPU it describes
    does not change while a process measures one config after another."""
    try:
        import cpuinfo
        info = cpuinfo.get_cpu_info()
    except Exception:
        return ()
    return tuple((k, info.get(k)) for k in PY_CPUINFO_KEYS)


def collect(repo_root: Path, make: str = "make", hyperfine: str = "hyperfine") -> dict[str, object]:
    described = machine.machine(repo_root, make)
    compiler = machine.make_compiler(repo_root, make)
    libc_name, libc_version = platform.libc_ver()
    # the libgomp the compiler links (its path) and, on Debian, the package's version
    libgomp = command_output([compiler, "-print-file-name=libgomp.so"])
    return {
        "date": now_iso(),
        "hostname": socket.gethostname(),
        "platform": platform.platform(),
        "kernel": platform.release(),
        "machine_id": described["machine_id"],
        "machine": described,
        "cpu_model": described["model_name"],
        "cpuinfo": dict(_py_cpuinfo()),
        "clock": clock(),
        "cores": machine.available_cores(),
        "cpu_count": os.cpu_count(),
        "container": machine.container(),
        "libc": {"name": libc_name or None, "version": libc_version or None,
                 "ldd": _first_line(command_output(["ldd", "--version"]))},
        "compiler": {"print_flags": machine.print_flags(repo_root, make),
                     "cc_version": _first_line(command_output([compiler, "--version"]))},
        "libgomp": {
            "path": os.path.realpath(libgomp) if libgomp and os.sep in libgomp else libgomp,
            "package_version": command_output(["dpkg-query", "-W", "-f=${Version}",
                                               "libgomp1"])},
        "hyperfine": command_output([hyperfine, "--version"]),
        "git": git_info(repo_root),
        "omp_env": {k: v for k, v in sorted(os.environ.items()) if k.startswith(("OMP_", "GOMP_"))},
        "python": sys.version.split()[0],
        "load_before": machine.load(),
    }
