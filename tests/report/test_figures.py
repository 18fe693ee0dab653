"""Every figure is written, as PNG and SVG, and the PNG is a valid image."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from harness.analysis import cells as acells
from harness.analysis import display, speedup
from harness.report.figures import accuracy as figaccuracy
from harness.report.figures import base as figbase
from harness.report.figures import sweeps as figsweeps
from harness.report.figures import trajectory as figtrajectory
from harness.report.sections.trajectory import read_trajectory
from harness.spec.facts import Variants
from harness.store import atomic
from PIL import Image

from fixture_results import FIXTURE_RESULTS, fixture_frame

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
GIF_SIGNATURE = b"GIF89a"


load = fixture_frame


def assert_valid_png(path: Path) -> None:
    assert path.read_bytes()[:8] == PNG_SIGNATURE
    with Image.open(path) as image:
        image.verify()
    with Image.open(path) as image:
        assert image.format == "PNG"
        width, height = image.size
        # figsize (7, 4.5) at 120 dpi: readable at 100% zoom.
        assert (width, height) == (840, 540)


def assert_figure_files(paths: list[Path], stem: Path) -> None:
    assert paths == [stem.with_name(f"{stem.name}.png"), stem.with_name(f"{stem.name}.svg")]
    assert_valid_png(paths[0])
    svg = paths[1].read_text(encoding="utf-8")
    assert svg.lstrip().startswith("<?xml") and "</svg>" in svg
    assert not list(stem.parent.glob(".*.tmp")), "a temporary file was left behind"


SWEEP_FIGURES: list[tuple[str, str]] = [  # the swept axis, the experiment sweeping it
    ("n", "particles"),
    ("n", "grid"),
    ("L", "square"),
    ("r", "radius"),
    ("threads", "threads"),
]


@pytest.mark.parametrize(("axis", "experiment"), SWEEP_FIGURES)
def test_time_figures_are_written(axis: str, experiment: str, tmp_path: Path,
                                  facts: Variants) -> None:
    stem = tmp_path / "figures" / f"{experiment}-time"
    assert_figure_files(figsweeps.fig_time_vs(load(experiment), stem, x=axis, variants=facts),
                        stem)


def test_the_memory_figure_draws_a_series_each_in_mib(tmp_path: Path, facts: Variants) -> None:
    import matplotlib as mpl

    rows = load("particles")
    rows["peak_rss_mib"] = 2.0 + rows["n"] * 1e-3  # MiB, growing with N
    with mpl.rc_context({"svg.fonttype": "none"}):
        paths = figsweeps.fig_memory_vs(rows, tmp_path / "memory", x="n", variants=facts)
    assert_figure_files(paths, tmp_path / "memory")
    svg = svg_text(paths[1])
    assert "peak resident memory [MiB]" in svg and "particles N" in svg
    assert all(f">{name} · " in svg for name in set(rows["variant"]))  # one series each


@pytest.mark.parametrize("metric", list(figsweeps.THREAD_METRICS))
def test_thread_metric_figures_are_written(metric: str, tmp_path: Path, facts: Variants) -> None:
    rows = speedup.with_speedup(load("threads"), facts, thread_baseline=True)
    stem = tmp_path / "metric"
    assert_figure_files(figsweeps.fig_thread_metric(rows, stem, y=metric, variants=facts,
                                                    title="Thread scaling"), stem)


@pytest.mark.parametrize("experiment", ["accuracy", "relative"])
def test_error_figure_is_written(experiment: str, tmp_path: Path, facts: Variants) -> None:
    stem = tmp_path / f"{experiment}-error"
    df = load(experiment)
    df = df[df["n"] == df["n"].max()]
    assert_figure_files(figaccuracy.fig_error_time(df, stem, variants=facts), stem)


def test_error_floor_is_a_decade_below_the_smallest_error() -> None:
    assert figaccuracy.error_floor(pd.Series([0.0, 3.1e-13, 2e-4])) == pytest.approx(1e-14)
    assert figaccuracy.error_floor(pd.Series([0.0, 0.0])) == pytest.approx(1e-17)


def trajectory() -> tuple[pd.DataFrame, float]:
    df = load("trajectory")
    row = df.iloc[0]
    path = FIXTURE_RESULTS / "trajectory" / "outputs" / f"{row['cell_id']}.txt"
    return read_trajectory(path), float(row["L"])


def test_trajectory_figure_and_animation_are_written(tmp_path: Path) -> None:
    traj, box = trajectory()
    assert traj["step"].nunique() == 10  # states 0..8 and the final block after 9 steps
    stem = tmp_path / "trajectory"
    assert_figure_files(figtrajectory.fig_trajectory(traj, stem, box=box), stem)
    gif = figtrajectory.gif_trajectory(traj, tmp_path / "animation", box=box)
    assert gif.read_bytes()[:6] == GIF_SIGNATURE
    with Image.open(gif) as image:
        assert image.n_frames == 10


def test_trajectory_subsamples_many_particles(tmp_path: Path) -> None:
    many = figtrajectory.MAX_TRAJECTORY_PARTICLES + 500
    traj = pd.DataFrame({
        "step": [0] * many + [1] * many,
        "particle": list(range(many)) * 2,
        "x": [float(i % 100) for i in range(2 * many)],
        "y": [float(i % 37) for i in range(2 * many)],
    })
    ids, x, _ = figtrajectory._trajectory_arrays(traj)
    assert len(ids) == figtrajectory.MAX_TRAJECTORY_PARTICLES and x.shape == (len(ids), 2)
    assert_valid_png(figtrajectory.fig_trajectory(traj, tmp_path / "many", box=100.0)[0])


def test_compact_numbers_for_ticks() -> None:
    assert [figbase.compact_number(v) for v in (5000, 20000, 1e5, 1e6, 1e7, 0.5, 64)] == [
        "5000", "20k", "100k", "1M", "10M", "0.5", "64",
    ]


def test_atomic_write_replaces_and_cleans_up(tmp_path: Path) -> None:
    target = tmp_path / "out.bin"
    target.write_bytes(b"old")
    atomic.atomic_write(target, lambda handle: handle.write(b"new"))
    assert target.read_bytes() == b"new"

    def fail(handle: object) -> None:
        raise RuntimeError("disk full")

    with pytest.raises(RuntimeError):
        atomic.atomic_write(target, fail)
    assert target.read_bytes() == b"new"
    assert [p.name for p in tmp_path.iterdir()] == ["out.bin"]


def test_a_wrapped_title_stays_inside_the_figure() -> None:
    fig, ax = figbase.new_figure()
    ax.plot([1, 2], [1, 2])
    figbase.set_title(ax, "A title long enough to wrap onto two lines: " * 2)
    fig.canvas.draw()
    title = ax.title.get_window_extent(fig.canvas.get_renderer())
    assert "\n" in ax.get_title()
    assert title.y1 <= fig.bbox.height
    axes_top = ax.get_window_extent(fig.canvas.get_renderer()).y1
    assert title.y0 >= axes_top  # and above the axes, not over the plot


# --- uncertainty and machines ---------------------------------------------------------------


def svg_text(path: Path) -> str:
    return path.read_text(encoding="utf-8")


def test_interval_errors_are_the_distances_to_the_interval_ends() -> None:
    rows = pd.DataFrame({"speedup": [2.0, 3.0, 4.0], "speedup_low": [1.5, np.nan, 4.0],
                         "speedup_high": [2.5, np.nan, 4.5]})
    bars = figbase.interval_errors(rows, "speedup")
    assert bars is not None
    assert bars.tolist() == [[0.5, 0.0, 0.0], [0.5, 0.0, 0.5]]
    assert figbase.interval_errors(rows.drop(columns=["speedup_low"]), "speedup") is None
    medians = pd.DataFrame({"wall_median_s": [1.0], "wall_median_ci_low_s": [0.9],
                            "wall_median_ci_high_s": [1.2]})
    bars = figbase.interval_errors(medians, "wall_median_s")
    assert bars is not None and np.allclose(bars.ravel(), [0.1, 0.2])


def with_two_machines(frame: pd.DataFrame) -> pd.DataFrame:
    """The cells as measured on two machines, the second 1.5x slower with known CIs."""
    fast = frame.assign(machine="fast box")
    slow = frame.assign(machine="slow box", wall_median_s=frame["wall_median_s"] * 1.5)
    both = pd.concat([fast, slow], ignore_index=True)
    both["wall_median_ci_low_s"] = both["wall_median_s"] * 0.95
    both["wall_median_ci_high_s"] = both["wall_median_s"] * 1.05
    return both


def test_threads_figures_draw_one_series_per_machine_with_error_bars(tmp_path: Path,
                                                                   facts: Variants) -> None:
    import matplotlib as mpl

    frame = with_two_machines(load("threads"))
    assert acells.series_keys(frame, "threads")[0] == "machine"
    with mpl.rc_context({"svg.fonttype": "none"}):  # text as <text>, so it can be read back
        time_paths = figsweeps.fig_time_vs(frame, tmp_path / "time", x="threads", variants=facts)
        speed_paths = figsweeps.fig_thread_metric(speedup.with_speedup(frame, facts,
                                                                       thread_baseline=True),
                                                  tmp_path / "speedup", y="speedup",
                                                  variants=facts)
        single = figsweeps.fig_time_vs(load("threads"), tmp_path / "single", x="threads",
                                       variants=facts)
    for paths in (time_paths, speed_paths):
        svg = svg_text(paths[1])
        assert "fast box" in svg and "slow box" in svg
    assert "95% interval" in svg_text(time_paths[1])
    assert "95% interval" not in svg_text(single[1]) and "threads p" in svg_text(single[1])


def test_long_legend_labels_wrap_and_lead_with_the_variant() -> None:
    """A series of one machine among several: the variant leads its label (the machine comes
    last), and a legend beside the axes wraps it rather than running off the figure."""
    label = display.series_label(("AMD EPYC (znver3) x2 (2257f28b)", "seq"),
                                (acells.MACHINE, "variant"))
    assert label == "seq · AMD EPYC (znver3) x2 (2257f28b)"
    wrapped = figbase.wrap_label(label)
    assert all(len(line) <= figbase.LEGEND_WRAP for line in wrapped.split("\n")), wrapped
    assert wrapped.replace("\n", " ") == label


def test_thread_counts_past_the_cores_are_shaded_and_named(tmp_path: Path, facts: Variants) -> None:
    import matplotlib as mpl

    frame = load("threads")  # 16 cores, 1-128 threads
    within = frame[frame["threads"] <= 16]
    with mpl.rc_context({"svg.fonttype": "none"}):
        past = figsweeps.fig_thread_metric(speedup.with_speedup(frame, facts,
                                                                thread_baseline=True),
                                           tmp_path / "past", y="efficiency", variants=facts)
        inside = figsweeps.fig_time_vs(within, tmp_path / "inside", x="threads", variants=facts)
    assert "threads &gt; cores (16)" in svg_text(past[1])
    assert "threads &gt; cores" not in svg_text(inside[1])


def test_close_thread_counts_keep_their_ticks_but_not_both_texts() -> None:
    assert figbase.spaced_labels(np.array([1, 2, 4, 8, 16, 20, 32, 64, 128.0])) == {
        1, 2, 4, 8, 16, 32, 64, 128}
    assert figbase.spaced_labels(np.array([1, 2, 16, 20.0])) == {1, 2, 20}
    assert figbase.spaced_labels(np.array([100, 110.0])) == {100, 110}
