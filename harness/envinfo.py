"""env.json and the machine identity: the machine, the tools and the flags a measurement ran with.

Two levels:
  machine()     what tells machines apart (CPU, ISA, `-march=native`, topology, memory, VM) and
                `machine_id`, a hash of it; part of every cell key, so it is on the cached path
                and must stay fast: /proc/cpuinfo, psutil and one compiler call, once per process.
  collect()     everything env.json records: the machine plus what can change between runs on it
                (clock, governor, kernel, C library, compiler flags, libgomp, OMP_*, hyperfine,
                git, load). Only called when a run measures.

Why /proc/cpuinfo is read here and py-cpuinfo only in collect(): py-cpuinfo's get_cpu_info()
runs its probe in a subprocess and took 1.2-1.4 s on the development machine (`time python -c
"import cpuinfo; cpuinfo.get_cpu_info()"`), too slow for a run whose cells are all cached.
"""

from __future__ import annotations

import contextlib
import datetime
import functools
import hashlib
import json
import os
import platform
import re
import shutil
import socket
import subprocess
import sys
from pathlib import Path

import psutil

CPUINFO = Path("/proc/cpuinfo")
LOADAVG = Path("/proc/loadavg")
CPU_SYS = Path("/sys/devices/system/cpu")
NODE_SYS = Path("/sys/devices/system/node")
DMI_SYS_VENDOR = Path("/sys/class/dmi/id/sys_vendor")
COMMAND_TIMEOUT_S = 30
MACHINE_ID_CHARS = 16
GIB = 1 << 30
# The ISA extensions the variants' hot loops can use with -march=native (cpuinfo flag names).
ISA_FLAGS = ("sse4_2", "avx", "avx2", "fma", "avx512f")
# Hypervisor vendors as /sys/class/dmi/id/sys_vendor names them.
VM_VENDORS = ("QEMU", "KVM", "VMware", "Xen", "Microsoft Corporation", "Amazon EC2", "Google",
              "innotek", "Parallels", "OpenStack", "BHYVE")
# The parts of machine() that go into machine_id: the hardware, which does not change between
# boots. Not the hostname (a container gets a new one at each boot), the clock or the kernel.
IDENTITY_KEYS = ("vendor", "model_name", "family", "model", "stepping", "isa", "march",
                 "sockets", "cores", "threads_per_core", "numa_nodes", "memory_gib", "vm")


def available_cores() -> int:
    """The cores this process may run on (affinity), falling back to the CPU count."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def command_output(argv: list[str], cwd: Path | None = None) -> str | None:
    """stdout of a command, stripped, or None when it is missing or fails."""
    try:
        done = subprocess.run(argv, cwd=cwd, capture_output=True, text=True,
                              timeout=COMMAND_TIMEOUT_S, check=False)
    except (OSError, subprocess.TimeoutExpired):
        return None
    return done.stdout.strip() if done.returncode == 0 else None


def read_text(path: Path) -> str | None:
    try:
        return path.read_text().strip()
    except OSError:
        return None


# --- the CPU ------------------------------------------------------------------------------


def parse_cpuinfo(text: str) -> list[dict[str, str]]:
    """/proc/cpuinfo as one dict per logical CPU."""
    cpus: list[dict[str, str]] = []
    current: dict[str, str] = {}
    for line in text.splitlines():
        if not line.strip():
            if current:
                cpus.append(current)
                current = {}
            continue
        key, _, value = line.partition(":")
        current[key.strip()] = value.strip()
    if current:
        cpus.append(current)
    return cpus


def _int(value: str | None) -> int | None:
    try:
        return int(value) if value is not None else None
    except ValueError:
        return None


def cpu_description(cpus: list[dict[str, str]]) -> dict[str, object]:
    """Vendor, model, family/model/stepping, ISA flags, sockets and threads from /proc/cpuinfo."""
    first = cpus[0] if cpus else {}
    flags = set(first.get("flags", "").split())
    sockets = len({c["physical id"] for c in cpus if "physical id" in c}) or None
    siblings, per_socket = _int(first.get("siblings")), _int(first.get("cpu cores"))
    threads_per_core = (siblings // per_socket if siblings and per_socket else None)
    return {
        "vendor": first.get("vendor_id"),
        "model_name": first.get("model name") or first.get("Model") or platform.processor()
        or None,
        "family": _int(first.get("cpu family")),
        "model": _int(first.get("model")),
        "stepping": _int(first.get("stepping")),
        "isa": [f for f in ISA_FLAGS if f in flags],
        "hypervisor_flag": "hypervisor" in flags,
        "sockets": sockets,
        "threads_per_core": threads_per_core,
    }


def numa_nodes() -> int | None:
    try:
        return len([p for p in NODE_SYS.iterdir() if re.fullmatch(r"node\d+", p.name)]) or None
    except OSError:
        return None


def compiler_command(repo_root: Path | None, make: str = "make") -> list[str]:
    """The compiler make uses, from `make -s print-flags` (its first word), else `cc`."""
    flags = print_flags(repo_root, make) if repo_root is not None else None
    return [flags.split()[0]] if flags else ["cc"]


@functools.cache
def print_flags(repo_root: Path, make: str = "make") -> str | None:
    return command_output([make, "-s", "print-flags"], cwd=repo_root)


@functools.cache
def native_march(compiler: str) -> str | None:
    """What `-march=native` resolves to for this compiler on this CPU (e.g. znver3)."""
    text = command_output([compiler, "-march=native", "-Q", "--help=target"])
    if text is None:
        return None
    match = re.search(r"^\s*-march=\s+(\S+)", text, re.MULTILINE)
    return match.group(1) if match else None


def virtualization(hypervisor_flag: bool) -> str | None:
    """The hypervisor (e.g. kvm), or None on bare metal.

    `systemd-detect-virt --vm` where it exists (a container is not a VM: `--container` is
    recorded apart, in collect()); else the DMI vendor, else the cpuinfo 'hypervisor' flag."""
    detected = command_output(["systemd-detect-virt", "--vm"])
    if detected:
        return detected
    if detected is None and shutil.which("systemd-detect-virt") is not None:
        return None  # it ran and said "none" (exit 1)
    vendor = read_text(DMI_SYS_VENDOR) or ""
    if any(vendor.startswith(v) for v in VM_VENDORS):
        return vendor
    return "vm" if hypervisor_flag else None


def container() -> str | None:
    detected = command_output(["systemd-detect-virt", "--container"])
    return detected if detected and detected != "none" else None


@functools.cache
def machine(repo_root: Path | None = None, make: str = "make") -> dict[str, object]:
    """The machine's description (compact; stored in every cell record) with `machine_id` and
    a short `label`. Cached per process: one compiler call a run."""
    text = read_text(CPUINFO) or ""
    cpu = cpu_description(parse_cpuinfo(text))
    cores = psutil.cpu_count(logical=False)
    logical = psutil.cpu_count(logical=True)
    if cpu["threads_per_core"] is None and cores and logical:
        cpu["threads_per_core"] = logical // cores
    described: dict[str, object] = {
        **{k: v for k, v in cpu.items() if k != "hypervisor_flag"},
        "march": native_march(compiler_command(repo_root, make)[0]),
        "sockets": cpu["sockets"] or 1,
        "cores": cores,
        "logical_cpus": logical,
        "numa_nodes": numa_nodes(),
        "memory_gib": round(psutil.virtual_memory().total / GIB),
        "vm": virtualization(bool(cpu["hypervisor_flag"])),
    }
    described["machine_id"] = machine_id(described)
    described["label"] = machine_label(described)
    return described


def machine_id(described: dict[str, object]) -> str:
    """16 hex chars of a hash of the hardware parts of a machine description."""
    canonical = json.dumps({k: described.get(k) for k in IDENTITY_KEYS}, sort_keys=True,
                           separators=(",", ":"))
    return hashlib.sha256(canonical.encode()).hexdigest()[:MACHINE_ID_CHARS]


def machine_label(described: dict[str, object]) -> str:
    """e.g. "AMD EPYC (znver3) x2": the model name, what -march=native chose, the CPUs."""
    name = str(described.get("model_name") or "unknown CPU")
    march = described.get("march")
    cpus = described.get("logical_cpus") or described.get("cores")
    return f"{name}{f' ({march})' if march else ''} x{cpus}"


# --- what can change between runs ---------------------------------------------------------


def load() -> dict[str, object]:
    """Load averages and the run queue (runnable tasks, this process included) right now."""
    one, five, fifteen = os.getloadavg()
    fields = (read_text(LOADAVG) or "").split()
    runnable = _int(fields[3].partition("/")[0]) if len(fields) > 3 else None
    return {"load1": one, "load5": five, "load15": fifteen, "runnable": runnable}


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
    version = command_output([*compiler_command(repo_root, make), "--version"])
    return {
        "print_flags": flags,
        "cc_version": version.splitlines()[0] if version else None,
    }


GENERATED_PATHS = ("results", "report")


def git_info(repo_root: Path) -> dict[str, object]:
    commit = command_output(["git", "rev-parse", "HEAD"], cwd=repo_root)
    # results/ and report/ are what measuring writes: a run's own output must not make the
    # sources it measured look modified.
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
    try:
        import cpuinfo
        info = cpuinfo.get_cpu_info()
    except Exception:
        return {}
    keys = ("brand_raw", "hz_advertised_friendly", "l2_cache_size", "l3_cache_size", "arch")
    return {k: info.get(k) for k in keys}


def collect(repo_root: Path, make: str = "make", hyperfine: str = "hyperfine",
            load_before: dict[str, object] | None = None) -> dict[str, object]:
    """Everything env.json records."""
    described = machine(repo_root, make)
    compiler = compiler_command(repo_root, make)[0]
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
        "load_before": load_before if load_before is not None else load(),
    }
