"""Work per thread: busy seconds and pair tests of each thread, per variant (the frame
harness.analysis.strategies.work_table builds)."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from harness.report.figures.base import compact_number, new_figure, save_figure, variant_color
from harness.spec.facts import Variants


def work_figure(work: pd.DataFrame, stem: Path, *, variants: Variants) -> list[Path]:
    """Two panels of grouped bars: busy seconds and pair tests per thread, per variant (its
    colour from `variants`, their facts)."""
    fig, panels = new_figure(margins={"left": 0.1, "right": 0.98, "bottom": 0.12, "top": 0.8,
                                      "wspace": 0.4}, ncols=2)
    shown = list(dict.fromkeys(work["variant"]))
    width = 0.8 / len(shown)
    for panel, column, label in ((panels[0], "busy_s", "busy seconds in the pair finder"),
                                 (panels[1], "pairs", "pair tests")):
        for k, v in enumerate(shown):
            rows = work[work["variant"] == v]
            x = rows["thread"].to_numpy() + (k - (len(shown) - 1) / 2) * width
            panel.bar(x, rows[column], width, color=variant_color(v, variants), label=v)
        panel.set_xlabel("thread")
        panel.set_ylabel(label)
        panel.set_xticks(sorted(work["thread"].unique()))
        panel.yaxis.set_major_formatter(lambda value, _pos: compact_number(value))
    handles, labels = panels[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="upper center", ncol=len(shown), frameon=False,
               bbox_to_anchor=(0.5, 0.92))
    fig.suptitle("Work per thread: the seed's p1 (static blocks of rows) against its repairs")
    return save_figure(fig, stem)
