"""The machine's identity and its load.

machine() is what tells machines apart (CPU, ISA, `-march=native`, topology, memory, VM) with
`machine_id`, a hash of it: part of every cell key, so it is on the cached path and must stay
fast: /proc/cpuinfo, psutil and one compiler call, once per process. sample_load() and
is_loaded() say whether other processes compete for the CPUs."""

import functools
import hashlib
import json
import os
import platform
import re
import shutil
import statistics
import subprocess
import time
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


def round_cores() -> list[int]:
    """The cores this process (and the timed runs, which inherit it) may run on."""
    try:
        return sorted(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return list(range(os.cpu_count() or 1))


def available_cores() -> int:
    return len(round_cores())


def command_output(argv: list[str], cwd: Path | None = None) -> str | None:
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


def parse_cpuinfo(text: str) -> list[dict[str, str]]:
    blocks = re.split(r"\n\s*\n", text)
    return [{key.strip(): value.strip() for key, _, value in
             (line.partition(":") for line in block.splitlines())}
            for block in blocks if block.strip()]


def _int(value: str | None) -> int | None:
    try:
        return int(value) if value is not None else None
    except ValueError:
        return None


def cpu_description(cpus: list[dict[str, str]]) -> dict[str, object]:
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


def make_compiler(repo_root: Path | None, make: str = "make") -> str:
    """The compiler make uses, from `make -s print-flags` (its first word), else `cc`."""
    flags = print_flags(repo_root, make) if repo_root is not None else None
    return flags.split()[0] if flags else "cc"


@functools.cache
def print_flags(repo_root: Path, make: str = "make") -> str | None:
    return command_output([make, "-s", "print-flags"], cwd=repo_root)


@functools.cache
def native_march(compiler: str) -> str | None:
    """What `-march=native` resolves to for this compiler on this CPU (e.g. znver3)."""
    text = command_output([compiler, "-march=native", "-Q", "--help=target"]) or ""
    match = re.search(r"^\s*-march=\s+(\S+)", text, re.MULTILINE)
    return match.group(1) if match else None


def virtualization(hypervisor_flag: bool) -> str | None:
    """The hypervisor (e.g. kvm), or None on bare metal: `systemd-detect-virt --vm` where it
    exists (a container is recorded apart), else the DMI vendor, else the cpuinfo flag."""
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
    cpu = cpu_description(parse_cpuinfo(read_text(CPUINFO) or ""))
    cores = psutil.cpu_count(logical=False)
    logical = psutil.cpu_count(logical=True)
    if cpu["threads_per_core"] is None and cores and logical:
        cpu["threads_per_core"] = logical // cores
    described: dict[str, object] = {
        **{k: v for k, v in cpu.items() if k != "hypervisor_flag"},
        "march": native_march(make_compiler(repo_root, make)),
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
    canonical = json.dumps({k: described.get(k) for k in IDENTITY_KEYS}, sort_keys=True,
                           separators=(",", ":"))
    return hashlib.sha256(canonical.encode()).hexdigest()[:MACHINE_ID_CHARS]


def machine_label(described: dict[str, object]) -> str:
    """e.g. "AMD EPYC (znver3) x2": the model name, what -march=native chose, the CPUs."""
    name = str(described.get("model_name") or "unknown CPU")
    march = described.get("march")
    cpus = described.get("logical_cpus") or described.get("cores")
    return f"{name}{f' ({march})' if march else ''} x{cpus}"


# A cell is `loaded` when, at its start, other runnable tasks (the run queue less this process)
# number at least this share of the cores: on 2 cores one busy neighbour takes a whole CPU from a
# 2-thread cell. The run queue and not the 1-minute load average decides, because the load
# average still carries this run's own previous cell for a minute (it is recorded beside).
LOADED_RUNNABLE_PER_CORE = 0.5
# The run queue flickers; the median of a few samples over ~50 ms ignores a passing task.
LOAD_SAMPLES = 5
LOAD_SAMPLE_INTERVAL_S = 0.01


def load() -> dict[str, object]:
    """Load averages and the run queue (runnable tasks, this process included) right now."""
    one, five, fifteen = os.getloadavg()
    fields = (read_text(LOADAVG) or "").split()
    runnable = _int(fields[3].partition("/")[0]) if len(fields) > 3 else None
    return {"load1": one, "load5": five, "load15": fifteen, "runnable": runnable}


def sample_load() -> dict[str, object]:
    """load(), with the median run queue over a few samples."""
    loads = [load()]
    for _ in range(LOAD_SAMPLES - 1):
        time.sleep(LOAD_SAMPLE_INTERVAL_S)
        loads.append(load())
    samples = [x["runnable"] for x in loads if x["runnable"] is not None]
    return {**loads[-1], "runnable": statistics.median_low(samples) if samples else None}


def is_loaded(load: dict[str, object], cores: int) -> bool:
    """Other runnable tasks >= LOADED_RUNNABLE_PER_CORE x cores (this process not counted)."""
    runnable = load.get("runnable")
    if not isinstance(runnable, int):
        return False
    return runnable - 1 >= LOADED_RUNNABLE_PER_CORE * cores
