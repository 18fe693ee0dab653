"""Child processes of a measurement: run one in its own process group under a timeout (the
whole group is killed past it or on Ctrl-C), its exit status, the tail of its stderr, and
where asked its peak resident memory, as build/peakrss reports it (docs/results.md, "Peak
memory", says why the harness cannot measure it itself)."""

import contextlib
import os
import signal
import subprocess
import tempfile
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from harness.plan.cellstore import peakrss_path
from harness.store import atomic
from harness.store.columns import CRASHED, FAILED, OK, TIMEOUT

STDERR_TAIL_CHARS = 2000
COMMAND_NOT_FOUND = 127  # the shell's exit status for a command it cannot find
SHELL_SIGNAL_BASE = 128  # a shell reports a child killed by signal N as 128 + N
SHELL_SIGNALS = 64  # the signals that can be N (Linux's real-time ones included)
LAST_LINES = 3  # the lines of stderr a one-line failure quotes
KIB_PER_MIB = 1024  # ru_maxrss is in KiB on Linux


@dataclass(frozen=True)
class ProcessResult:
    returncode: int | None  # None: killed at the timeout
    stderr: str
    seconds: float
    # The largest resident set of the run, in KiB: the command's own or that of any
    # descendant it waited for (a shell's commands; the largest, not their sum). None where
    # not asked for, where build/peakrss is not built, or where the run did not end.
    max_rss_kib: int | None = None


def run_process(argv: Sequence[str], env: Mapping[str, str], timeout_s: float,
                stdout: Path | None = None, memory: bool = False) -> ProcessResult:
    """Run argv in its own process group with stdout to a file (or /dev/null); past the
    timeout, or on any exception (Ctrl-C), the whole group is killed. With `memory`, under
    build/peakrss (where built), which reports its peak resident memory."""
    started = time.monotonic()
    target = stdout if stdout is not None else Path(os.devnull)
    with atomic.writing(target):
        out = target.open("wb")
    helper = peakrss_path() if memory else None
    if helper is not None and not os.access(helper, os.X_OK):
        helper = None
    with out, tempfile.TemporaryFile() as err, tempfile.TemporaryFile() as report:
        command = list(argv) if helper is None else [str(helper), str(report.fileno()), *argv]
        try:
            proc = subprocess.Popen(command, stdout=out, stderr=err,
                                    stdin=subprocess.DEVNULL, env=dict(env),
                                    start_new_session=True,
                                    pass_fds=() if helper is None else (report.fileno(),))
        except OSError as exc:
            return ProcessResult(COMMAND_NOT_FOUND, f"cannot run {argv[0]}: {exc.strerror}\n", 0.0)
        returncode: int | None = None
        try:
            returncode = proc.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            pass
        finally:  # the whole group, past the timeout or on any exception (Ctrl-C)
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
        err.seek(0)
        stderr = err.read().decode(errors="replace")
        report.seek(0)  # build/peakrss's report: the run's ru_maxrss in KiB
        reported = report.read().decode(errors="replace").strip()
    reports = helper is not None and returncode is not None and reported.isdigit()
    return ProcessResult(returncode, stderr, time.monotonic() - started,
                         int(reported) if reports else None)


def peak_mib(*runs: ProcessResult) -> float | None:
    """A cell's peak memory in MiB: the largest resident set among the runs of its program on
    its input that the harness waited for (a launcher's ru_maxrss is already the largest of the
    ranks it waits for on its node); None where none reports one."""
    found = [run.max_rss_kib for run in runs if run.max_rss_kib is not None]
    return max(found) / KIB_PER_MIB if found else None


def run_captured(argv: Sequence[str], env: Mapping[str, str], timeout_s: float,
                 scratch: Path | None = None, keep: Path | None = None, memory: bool = False
                 ) -> tuple[ProcessResult, str]:
    """run_process with stdout to a fresh file beside `scratch` (the system's temporary
    directory by default): the run and, where it exited 0, its stdout (moved to `keep`);
    "" otherwise, unread. Bytes that are not UTF-8 are read as U+FFFD: such output fails its
    validation, not the harness. A run that did not finish where that file can take no more
    (a full disk, a file-size limit) failed for want of room, not of its own: a StorageError
    naming the place (atomic.check_room), and no result. `memory` as for run_process."""
    text = ""
    with atomic.temporary(scratch or Path(tempfile.gettempdir()) / "collide-stdout") as out:
        done = run_process(argv, env, timeout_s, out, memory)
        if done.returncode not in (0, None):
            atomic.check_room(out, f"the output of {Path(argv[0]).name}")
        if done.returncode == 0:
            text = out.read_text(errors="replace")
            if keep is not None:
                with atomic.writing(keep):
                    keep.parent.mkdir(parents=True, exist_ok=True)
                    os.replace(out, keep)
    return done, text


def exit_status(returncode: int | None) -> tuple[str, int | None]:
    """(status, exit_code) of one run: ok, failed (exit != 0), crashed (signal), timeout."""
    if returncode is None:
        return TIMEOUT, None
    if returncode == 0:
        return OK, 0
    return (CRASHED if returncode < 0 else FAILED), returncode


def tail(text: str) -> str:
    return text[-STDERR_TAIL_CHARS:]


def signal_of(code: int | None) -> int | None:
    """The signal that killed a run: a negative code's, or a shell's 128 + N; else None."""
    if code is None:
        return None
    if code < 0:
        return -code
    shell = code - SHELL_SIGNAL_BASE
    return shell if 0 < shell <= SHELL_SIGNALS else None


def failure(what: str, done: ProcessResult, timeout_s: float) -> str:
    """One line on why a run did not finish: its timeout, signal or exit and its last lines."""
    if done.returncode is None:
        return f"{what} passed the {timeout_s:g} s timeout"
    code = done.returncode
    last = " | ".join(done.stderr.strip().splitlines()[-LAST_LINES:])
    number = signal_of(code)
    if code == COMMAND_NOT_FOUND:
        why = "exit 127: command not found"
    elif number is not None:
        try:
            name = signal.Signals(number).name
        except ValueError:
            name = f"signal {number}"
        why = f"killed by {name}" + (f" (exit {code})" if code > 0 else "")
    else:
        why = f"exit {code}"
    return f"{what}: {why}" + (f": {last}" if last else "")
