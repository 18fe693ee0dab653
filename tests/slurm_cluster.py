"""A throwaway single-node Slurm cluster for the tests, from Debian's packages.

Everything lives in one private directory: the munge key and socket, slurm.conf, the
controller's state, the node's spool, the logs and the jobcomp/filetxt completion file. The
daemons (munged, slurmctld, slurmd) run in the foreground as children of this process, on
ports picked free at start, so two clusters (two test sessions) on one machine do not meet;
clients reach this one through SLURM_CONF (`cluster.env`). There is no systemd on the test
machines: nothing here goes through an init system, and teardown signals the daemons by pid.

The settings are the ones known to work on the CI machine kind: select/cons_tres with CR_Core,
proctrack/linuxproc and task/none (no cgroups in the container), jobcomp/filetxt (final job
states in a file, no database), the node line of `slurmd -C` renamed to localhost at
127.0.0.1, batch_sched_delay=0 and KillWait=5 (a cancelled or timed-out task is SIGKILLed 5 s
after SIGTERM).
"""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import signal
import socket
import subprocess
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

PACKAGES = ("slurmctld", "slurmd", "slurm-client", "munge")
# command -> the package that provides it
COMMANDS = {"slurmctld": "slurmctld", "slurmd": "slurmd", "sbatch": "slurm-client",
            "squeue": "slurm-client", "scontrol": "slurm-client", "scancel": "slurm-client",
            "munged": "munge", "mungekey": "munge"}
PARTITION = "debug"
NODE = "localhost"
MUNGE_KEY_BYTES = 1024
START_TIMEOUT_S = 60.0
STOP_TIMEOUT_S = 15.0
POLL_S = 0.1
APT_TIMEOUT_S = 600.0


class ClusterUnavailable(Exception):
    """The packages are missing and cannot be installed here (the reason is the message)."""


def missing_commands() -> list[str]:
    return [cmd for cmd in COMMANDS if shutil.which(cmd) is None]


def ensure_packages() -> None:
    """Install Debian's Slurm and munge when missing and we are root; else ClusterUnavailable."""
    if not missing_commands():
        return
    if os.geteuid() != 0:
        raise ClusterUnavailable(
            f"Slurm is not installed ({', '.join(missing_commands())} missing) and this is not "
            f"root: run `scripts/setup.sh --test` as root, or apt-get install {' '.join(PACKAGES)}")
    if shutil.which("apt-get") is None:
        raise ClusterUnavailable("Slurm is not installed and there is no apt-get to install it")
    env = {**os.environ, "DEBIAN_FRONTEND": "noninteractive"}
    for argv in (["apt-get", "update", "-q"],
                 ["apt-get", "install", "-y", "-q", "--no-install-recommends", *PACKAGES]):
        done = subprocess.run(argv, env=env, capture_output=True, text=True, check=False,
                              timeout=APT_TIMEOUT_S)
        if done.returncode != 0:
            raise ClusterUnavailable(f"cannot install Slurm ({' '.join(argv)}): "
                                     f"{done.stderr.strip()[-300:]}")
    if missing_commands():
        raise ClusterUnavailable(f"still missing after apt-get: {', '.join(missing_commands())}")


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def node_line() -> str:
    """`slurmd -C`'s description of this machine, as node `localhost` at 127.0.0.1."""
    done = subprocess.run(["slurmd", "-C"], capture_output=True, text=True, check=True)
    line = next(ln for ln in done.stdout.splitlines() if ln.startswith("NodeName="))
    line = re.sub(r"^NodeName=\S+", f"NodeName={NODE} NodeAddr=127.0.0.1", line)
    # RealMemory: leave it out, so a job never waits on a memory figure that drifts.
    return re.sub(r"\s*RealMemory=\d+", "", line)


@dataclass
class SlurmCluster:
    root: Path
    processes: dict[str, subprocess.Popen[bytes]] = field(default_factory=dict)
    started_s: float = 0.0  # seconds start() took

    @property
    def conf(self) -> Path:
        return self.root / "slurm.conf"

    @property
    def jobcomp(self) -> Path:
        return self.root / "jobcomp.txt"

    @property
    def env(self) -> dict[str, str]:
        """os.environ with SLURM_CONF pointing at this cluster (what its clients need)."""
        return {**os.environ, "SLURM_CONF": str(self.conf)}

    def log(self, name: str) -> str:
        path = self.root / "log" / f"{name}.log"
        return path.read_text(errors="replace") if path.is_file() else ""

    # --- start ---

    def write_files(self) -> None:
        for sub in ("munge", "state", "spool", "log"):
            (self.root / sub).mkdir(parents=True, exist_ok=True)
        self.root.chmod(0o755)
        (self.root / "munge").chmod(0o755)  # munged refuses a socket directory with mode 700
        key = self.root / "munge" / "munge.key"
        key.write_bytes(os.urandom(MUNGE_KEY_BYTES))
        key.chmod(0o600)
        r = self.root
        self.conf.write_text("\n".join([
            "ClusterName=collidetest",
            f"SlurmctldHost={NODE}(127.0.0.1)",
            f"SlurmctldPort={free_port()}",
            f"SlurmdPort={free_port()}",
            "SlurmUser=root",
            "SlurmdUser=root",
            "AuthType=auth/munge",
            "CredType=cred/munge",
            f"AuthInfo=socket={r}/munge/munge.socket",
            f"StateSaveLocation={r}/state",
            f"SlurmdSpoolDir={r}/spool",
            f"SlurmctldPidFile={r}/slurmctld.pid",
            f"SlurmdPidFile={r}/slurmd.pid",
            f"SlurmctldLogFile={r}/log/slurmctld.log",
            f"SlurmdLogFile={r}/log/slurmd.log",
            "ProctrackType=proctrack/linuxproc",
            "TaskPlugin=task/none",
            "SelectType=select/cons_tres",
            "SelectTypeParameters=CR_Core",
            "JobCompType=jobcomp/filetxt",
            f"JobCompLoc={self.jobcomp}",
            "SchedulerParameters=batch_sched_delay=0",
            "KillWait=5",
            "MpiDefault=none",
            "ReturnToService=2",
            "InactiveLimit=0",
            "SlurmctldTimeout=30",
            "SlurmdTimeout=30",
            node_line() + " State=UNKNOWN",
            f"PartitionName={PARTITION} Nodes={NODE} Default=YES MaxTime=INFINITE State=UP",
            "",
        ]))

    def spawn(self, name: str, argv: list[str]) -> None:
        out = (self.root / "log" / f"{name}.out").open("wb")
        with out:
            self.processes[name] = subprocess.Popen(
                argv, stdin=subprocess.DEVNULL, stdout=out, stderr=subprocess.STDOUT,
                env=self.env, start_new_session=True)

    def wait_for(self, what: str, ready: object) -> None:
        deadline = time.monotonic() + START_TIMEOUT_S
        while time.monotonic() < deadline:
            for name, proc in self.processes.items():
                if proc.poll() is not None:
                    raise RuntimeError(f"{name} exited with {proc.returncode} while waiting for "
                                       f"{what}: {self.log(name)[-1500:]}"
                                       f"{(self.root / 'log' / f'{name}.out').read_text()[-500:]}")
            if callable(ready) and ready():
                return
            time.sleep(POLL_S)
        raise RuntimeError(f"timed out waiting for {what}; slurmctld log: "
                           f"{self.log('slurmctld')[-1500:]} slurmd log: "
                           f"{self.log('slurmd')[-1500:]}")

    def start(self) -> None:
        started = time.monotonic()
        self.write_files()
        m = self.root / "munge"
        self.spawn("munged", ["munged", "--foreground", "--force", f"--socket={m}/munge.socket",
                              f"--key-file={m}/munge.key", f"--pid-file={m}/munged.pid",
                              f"--seed-file={m}/munged.seed",
                              f"--log-file={self.root}/log/munged.log"])
        self.wait_for("munged's socket", (m / "munge.socket").exists)
        self.spawn("slurmctld", ["slurmctld", "-D", "-i"])
        self.wait_for("slurmctld", lambda: self.scontrol_ok(["ping"], "UP"))
        self.spawn("slurmd", ["slurmd", "-D", "-N", NODE])
        self.wait_for("the node to be idle", self.node_idle)
        self.started_s = time.monotonic() - started

    def scontrol_ok(self, args: list[str], expect: str) -> bool:
        done = subprocess.run(["scontrol", *args], env=self.env, capture_output=True, text=True,
                              check=False)
        return done.returncode == 0 and expect in done.stdout

    def node_idle(self) -> bool:
        done = subprocess.run(["sinfo", "-h", "-n", NODE, "-o", "%T"], env=self.env,
                              capture_output=True, text=True, check=False)
        return done.returncode == 0 and done.stdout.strip() == "idle"

    # --- stop ---

    def cancel_all(self) -> None:
        """scancel every job and wait (bounded) until none is left running."""
        if "slurmctld" not in self.processes or self.processes["slurmctld"].poll() is not None:
            return
        subprocess.run(["scancel", "--full", "--partition", PARTITION], env=self.env,
                       capture_output=True, check=False)
        deadline = time.monotonic() + STOP_TIMEOUT_S
        while time.monotonic() < deadline:
            done = subprocess.run(["squeue", "-h", "-o", "%i"], env=self.env,
                                  capture_output=True, text=True, check=False)
            if done.returncode != 0 or not done.stdout.strip():
                return
            time.sleep(POLL_S * 5)

    def stop(self) -> float:
        """Cancel the jobs, then stop slurmd, slurmctld and munged by pid; the seconds taken."""
        started = time.monotonic()
        self.cancel_all()
        for name in ("slurmd", "slurmctld", "munged"):
            proc = self.processes.pop(name, None)
            if proc is None:
                continue
            with contextlib.suppress(ProcessLookupError):
                proc.send_signal(signal.SIGTERM)
            try:
                proc.wait(timeout=STOP_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        return time.monotonic() - started


def start_cluster(parent: Path | None = None) -> SlurmCluster:
    """ensure_packages(), then a started cluster in a fresh directory (stop it, then remove it)."""
    ensure_packages()
    root = Path(tempfile.mkdtemp(prefix="collide-slurm-", dir=parent))
    cluster = SlurmCluster(root)
    try:
        cluster.start()
    except BaseException:
        cluster.stop()
        raise
    return cluster


def main() -> None:
    """`python tests/slurm_cluster.py`: start a cluster, print its SLURM_CONF, keep it until
    SIGTERM or Ctrl-C (for trying the Slurm executor by hand)."""
    cluster = start_cluster()
    print(f"SLURM_CONF={cluster.conf}  (started in {cluster.started_s:.2f} s)", flush=True)
    signal.signal(signal.SIGTERM, lambda *_: (_ for _ in ()).throw(KeyboardInterrupt))
    try:
        while True:
            time.sleep(3600)
    except KeyboardInterrupt:
        pass
    finally:
        print(f"stopped in {cluster.stop():.2f} s", flush=True)
        shutil.rmtree(cluster.root, ignore_errors=True)


if __name__ == "__main__":
    main()
