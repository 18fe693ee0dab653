"""An experiment as the report reads it: one machine's rows of the read model
(harness.analysis.results) with their ratios paired by round and divergence curves, and the
print-mode outputs it kept (env.json is read by harness.report.pipeline)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

from harness.analysis import results
from harness.analysis.cells import MACHINE
from harness.analysis.paired import paired
from harness.analysis.serving import serving
from harness.errors import HarnessError
from harness.report.machines import UNKNOWN_ID
from harness.spec.facts import BASELINE, Variants
from harness.spec.output import OutputFormatError, parse_output, states_by_step
from harness.store.layout import ExperimentDir
from harness.store.records import MACHINE_KEY


@dataclass(frozen=True, eq=False)
class Experiment:
    """One results/<name>/ directory: its cells and its title."""

    name: str
    directory: ExperimentDir
    title: str
    frame: pd.DataFrame
    divergence: pd.DataFrame | None = None  # the checks' divergence curves, where some cell has
    ratios: pd.DataFrame | None = None  # its cells' ratios paired by round, where there are
    variants: Variants = field(default_factory=Variants)  # facts of the variants it measured


def read_trajectory(path: Path) -> pd.DataFrame:
    """A print-mode output (SPEC section 3) as rows step, particle, x, y: the states
    s = 0..S-1 and the final block at S."""
    try:
        output = parse_output(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as e:
        raise HarnessError(f"{path}: cannot read output: {e}") from e
    except OutputFormatError as e:
        raise HarnessError(f"{path}: not a print-mode output (SPEC section 3): {e}") from None
    steps, particles, positions = states_by_step(output)
    traj = pd.DataFrame({"step": steps, "particle": particles,
                         "x": positions[:, 0], "y": positions[:, 1]})
    if traj.duplicated(["step", "particle"]).any():
        raise HarnessError(f"{path}: a particle appears twice in one step")
    return traj


def load_experiment(found: ExperimentDir | results.Experiment, machine: str | None = None,
                    label: str = "") -> Experiment:
    """One experiment read and checked (HarnessError naming what is wrong); with `machine`
    (an id), only that machine's cells, which go by `label` where given; a serial variant's
    cell at each thread count it serves (harness.analysis.serving)."""
    loaded = found if isinstance(found, results.Experiment) else results.load_experiment(found)
    frame = loaded.frame
    ratios = paired(loaded.ratios(BASELINE))
    if machine is not None:
        frame, ratios = _of_machine(frame, machine), _of_machine(ratios, machine)
        if label and frame is not None:
            frame[MACHINE] = label
    frame = serving(frame, loaded.variants)  # which variants are serial, their facts say
    return Experiment(loaded.name, loaded.directory, loaded.title, frame, loaded.divergence,
                      ratios, loaded.variants)


def _of_machine(frame: pd.DataFrame | None, machine: str) -> pd.DataFrame | None:
    """The rows measured on the machine (an id; UNKNOWN_ID for rows without one)."""
    if frame is None or MACHINE_KEY not in frame.columns:
        return frame
    ids = frame[MACHINE_KEY].fillna("").astype(str).str.strip()
    return frame[ids.replace("", UNKNOWN_ID) == machine].reset_index(drop=True)

