"""Programs, implementations of the model written elsewhere (`programs:` in a config, parsed by
harness.spec.programs); docs/programs.md, "Where the code is", says what each module does.

The core imports none of it: the command line lends it `start_program` (Hooks.program_runner)
and REPORT. Standard library only here: what measures or draws is imported when a program's
cell is measured or an experiment's section is built.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from harness.report.parts import ReportFeature

if TYPE_CHECKING:
    from harness.report.parts import Count

NAME = "programs"


def _on_call(module: str, name: str) -> Callable[..., Any]:
    """harness.programs.MODULE's `name`, that module imported at the first call."""
    def call(*args: Any, **kwargs: Any) -> Any:
        return getattr(importlib.import_module(f"{__name__}.{module}"), name)(*args, **kwargs)

    return call


# A program's cell: its run and its check against seq (Hooks.program_runner).
start_program = _on_call("cell", "start_program")


def sentence(total: Count) -> str:
    """The summary's fidelity words on the program cells of the experiments."""
    return (f"{total.passed} of {total.cells} program cells agree with seq (identical, "
            f"rounding or diverges) ([programs](#{total.anchor}))")


# The experiment's programs section, where it has program cells, and the count of its program
# cells that agree with seq.
REPORT = ReportFeature(NAME, "programs", _on_call("section", "build"),
                       _on_call("section", "count"), sentence)
