"""Measure cells by id in a fresh process, e.g. a Slurm task on a compute node:

    python -m harness.worker --config PATH --results-dir DIR [--quick] CELL_ID [CELL_ID ...]

It plans the config again (as run.py would, with the same --quick), finds each cell by its id,
measures it and writes its record atomically to <results-dir>/<name>/cells/<id>.json, exactly
as a local run does (Measurer.measure_and_save). It builds nothing and consults no cached
record: the caller sends only pending cells, with the binaries already built on a shared file
system. An id that is not a cell of the plan (or whose binaries are missing) is one error line
and exit 2, before anything is measured.
"""

from __future__ import annotations

import argparse
import signal
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import cast

from harness import envinfo, results
from harness.cellstore import CellStore
from harness.config import load_config
from harness.errors import HarnessError
from harness.measure import Measurer
from harness.plan import plan_cells
from harness.store import MACHINES, write_env

REPO_ROOT = Path(__file__).resolve().parent.parent
EXIT_ERROR = 2
MACHINE_KEY = "machine_id"  # the part of a cell key that names the machine (when present)
EXIT_INTERRUPTED = 130


def parse_args(argv: Sequence[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="python -m harness.worker",
                                     description="Measure planned cells of a config by id.")
    parser.add_argument("--config", type=Path, required=True, help="the experiment YAML file")
    parser.add_argument("--results-dir", type=Path, required=True, help="results root")
    parser.add_argument("--quick", action="store_true", help="the cells of a --quick run")
    parser.add_argument("--repo-root", type=Path, default=REPO_ROOT,
                        help="repository whose build/ holds the binaries (default: this one)")
    parser.add_argument("--hyperfine", default="hyperfine", help="hyperfine executable")
    parser.add_argument("cell_ids", nargs="+", metavar="CELL_ID",
                        help="cell ids, or their machine-independent ids (portable_id)")
    return parser.parse_args(argv)


def measure_cells(config_path: Path, results_root: Path, quick: bool, repo_root: Path,
                  cell_ids: Sequence[str], hyperfine: str = "hyperfine") -> None:
    config = load_config(config_path)
    store = CellStore(plan_cells(config, quick), repo_root.resolve(), results_root.resolve())
    cells = store.cells_by_id()
    portable = {portable_id(cast(dict[str, object], store.cell_key(cell))): cid
                for cid, cell in cells.items()}
    chosen = [cid if cid in cells else portable.get(cid) for cid in cell_ids]
    unknown = [given for given, cid in zip(cell_ids, chosen, strict=True) if cid is None]
    if unknown:
        raise HarnessError(f"{config_path}: no planned cell with id {' '.join(unknown)}"
                           f"{' (--quick)' if quick else ''}")
    measurer = Measurer(store, hyperfine)
    for cid in chosen:
        assert cid is not None
        measurer.measure_and_save(cells[cid], cid)
    # the machine and tools of this node, once per machine (a submitter elsewhere cannot)
    if not (store.directory / MACHINES / f"{store.machine_id}.json").is_file():
        write_env(store.directory, envinfo.collect(repo_root.resolve(), hyperfine=hyperfine))


def portable_id(key: Mapping[str, object]) -> str:
    """A cell's id computed without the machine it is measured on (a key's `machine_id`):
    what a submitter names a cell by before it knows which node will measure it (Slurm). The
    worker takes it as well as a cell id; the record is written under the cell id of the
    machine that measured it."""
    return results.cell_id({k: v for k, v in key.items() if k != MACHINE_KEY})


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(sys.argv[1:] if argv is None else argv)
    signal.signal(signal.SIGTERM, _terminate)  # Slurm's time limit: kill the cell's processes
    try:
        measure_cells(args.config, args.results_dir, args.quick, args.repo_root, args.cell_ids,
                      args.hyperfine)
    except HarnessError as exc:
        sys.stderr.write(f"error: {exc}\n")
        return EXIT_ERROR
    except KeyboardInterrupt:
        sys.stderr.write("interrupted: the cells finished so far are saved\n")
        return EXIT_INTERRUPTED
    return 0


def _terminate(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


if __name__ == "__main__":
    sys.exit(main())
