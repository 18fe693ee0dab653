"""A cell that runs as MPI ranks: started by Open MPI's mpirun (`mpirun -np R`), placed as the
machine allows, its --timing's MPI figures read. A rank count beyond the machine's cores is
refused unless the config asks for oversubscription (`executor: {oversubscribe: true}`); a
machine without mpirun is told how to get it."""

import os
import shutil
from collections.abc import Mapping
from dataclasses import dataclass, replace

from harness.errors import HarnessError
from harness.measure.timing import numbers
from harness.spec.facts import MPI_INSTALL
from harness.store.measured import Ranks

MPIRUN = "mpirun"
# Open MPI refuses to start as root unless told twice; a measurement under root is asked to.
ROOT_ENV = {"OMPI_ALLOW_RUN_AS_ROOT": "1", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1"}


def mpirun() -> str:
    """The mpirun on PATH; a HarnessError saying how to install it where there is none."""
    found = shutil.which(MPIRUN)
    if found is None:
        raise HarnessError(f"{MPIRUN} not found: the config runs MPI ranks (`ranks:`, or a "
                           f"variant whose --describe says mpi); install Open MPI: {MPI_INSTALL}")
    return found


@dataclass(frozen=True)
class Placement:
    """How mpirun starts a cell's ranks."""

    argv: tuple[str, ...]  # the words before the binary
    binding: str
    oversubscribed: bool  # ranks and threads together are more than the cores


def check_ranks(ranks: int, cores: int, oversubscribe: bool, where: str) -> None:
    """A HarnessError where more ranks than cores are asked for without oversubscription."""
    if ranks > cores and not oversubscribe:
        raise HarnessError(f"{where}: key 'ranks': {ranks} ranks exceed the {cores} cores of "
                           "this machine; set executor: {oversubscribe: true} to run them "
                           "anyway (ranks then share cores)")


def placement(ranks: int, threads: int, cores: int, oversubscribe: bool) -> Placement:
    """mpirun's words for `ranks` ranks of `threads` threads each. A rank of one thread is
    bound to a core (Open MPI's own choice for a few ranks); a rank of several is left unbound,
    so that its threads spread over the cores instead of sharing one."""
    binding = "core" if threads == 1 and ranks <= cores else "none"
    argv = [mpirun(), "-np", str(ranks), "--bind-to", binding]
    if ranks > cores and oversubscribe:
        argv.append("--oversubscribe")
    return Placement(tuple(argv), binding, ranks * threads > cores)


# On one machine Open MPI's own messaging layer (shared memory between the ranks) is the one
# that serves: its default first probes every fabric it was built for (PSM, OFI, UCX), which
# cost about 0.2 s of a run's start on a machine that has none (docs/mpi.md, "Start-up").
ONE_NODE_ENV = {"OMPI_MCA_pml": "ob1"}
OVERSUBSCRIBE_VAR = "OMPI_MCA_rmaps_base_oversubscribe"
RECORDED_PREFIX = "OMPI_MCA_"  # what a record keeps of how Open MPI was set


def environment(given: Mapping[str, str], oversubscribe: bool) -> dict[str, str]:
    """What a rank's environment adds to `given`: mpirun's consent to run as root, where it
    is; where the ranks share one node the one-node messaging layer, unless `given` chooses
    one; and where the config allows more ranks than cores, mpirun's consent to that too (a
    program's own mpirun has no flag of ours)."""
    env = dict(ROOT_ENV) if os.geteuid() == 0 else {}
    if given.get("SLURM_JOB_NUM_NODES", "1") == "1":
        env.update({k: v for k, v in ONE_NODE_ENV.items() if k not in given})
    if oversubscribe:
        env.setdefault(OVERSUBSCRIBE_VAR, "1")
    return env


def timing_fields(timing: Mapping[str, object], place: Placement) -> Ranks:
    """The record's MPI group: the placement and the --timing figures."""
    figures = {k: None if v is None else float(v) for k, v in numbers(timing, Ranks).items()}
    return replace(Ranks(**figures), ranks_oversubscribed=place.oversubscribed,
                   ranks_binding=place.binding)
