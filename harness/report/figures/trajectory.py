"""Trajectories of a print-mode run (the course report's Figure 7), still and animated."""

from pathlib import Path
from typing import IO

import matplotlib as mpl
import numpy as np
import pandas as pd
from matplotlib.cm import ScalarMappable
from matplotlib.collections import LineCollection
from matplotlib.colors import Normalize
from matplotlib.lines import Line2D
from matplotlib.patches import Rectangle
from PIL import Image, ImageDraw, ImageFont

from harness.report.figures import base
from harness.store import atomic

TRAJECTORY_CMAP = "turbo"
# Room on the left for the legend; the square axes and its colorbar take the rest.
MARGINS: dict[str, float] = {**base.MARGINS, "left": 0.26}
MAX_TRAJECTORY_PARTICLES = 2000  # more would be an unreadable smear; plot an even subsample
GIF_PIXELS = 480  # frame width; the box fills it less the padding
GIF_PAD = 12
GIF_TITLE_PX = 36  # room above the box for the step counter
GIF_FONT_PX = 18
GIF_DOT_PX = 4
GIF_COLORS = 128
GIF_FRAME_MS = 600


def _trajectory_arrays(traj: pd.DataFrame) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Particle indices and their positions as (particles, states) arrays, subsampled evenly
    down to MAX_TRAJECTORY_PARTICLES."""
    xs = traj.pivot(index="particle", columns="step", values="x").sort_index()
    ys = traj.pivot(index="particle", columns="step", values="y").sort_index()
    ids = xs.index.to_numpy()
    count = min(len(ids), MAX_TRAJECTORY_PARTICLES)  # all, or an even subsample
    keep = np.linspace(0, len(ids) - 1, count).round().astype(int)
    return ids[keep], xs.to_numpy()[keep], ys.to_numpy()[keep]


def fig_trajectory(
    traj: pd.DataFrame, out: Path, *, box: float, title: str | None = None
) -> list[Path]:
    """Every particle's path through the printed states, colored by particle index.

    `traj` has columns step, particle, x, y (one row per particle and state). Consecutive
    states are joined by straight segments; a bounce inside a step is not drawn.
    """
    ids, x, y = _trajectory_arrays(traj)
    states = x.shape[1]
    norm = Normalize(vmin=float(ids.min()), vmax=float(max(ids.max(), ids.min() + 1)))
    cmap = mpl.colormaps[TRAJECTORY_CMAP]
    fig, ax = base.new_figure(margins=MARGINS)
    colors = cmap(norm(ids))
    # Line segments joining each particle's consecutive states: (particles*(states-1), 2, 2).
    points = np.stack([x, y], axis=-1)
    segments = np.stack([points[:, :-1], points[:, 1:]], axis=2).reshape(-1, 2, 2)
    ax.add_collection(LineCollection(segments, colors=np.repeat(colors, states - 1, axis=0),
                                     lw=1.0, alpha=0.75))
    ax.scatter(x[:, 0], y[:, 0], s=10, facecolors="none", edgecolors=colors, lw=0.8)
    ax.scatter(x[:, -1], y[:, -1], s=18, c=colors, edgecolors="black", lw=0.4)
    ax.add_patch(Rectangle((0, 0), box, box, fill=False, lw=1.5, color="black"))
    pad = box * 0.02
    ax.set_xlim(-pad, box + pad)
    ax.set_ylim(-pad, box + pad)
    ax.set_aspect("equal")
    ax.set_xlabel("x [length units]")
    ax.set_ylabel("y [length units]")
    fig.colorbar(ScalarMappable(norm=norm, cmap=cmap), ax=ax, label="particle index i")
    base.set_title(ax, title or f"Trajectories over {states - 1} steps ({len(ids)} particles)")
    handles = [Line2D([], [], ls="none", marker="o", mfc="none", mec="gray", label="start (s = 0)"),
               Line2D([], [], ls="none", marker="o", mfc="gray", mec="black",
                      label=f"end (s = {states - 1})"),
               Line2D([], [], color="gray", label="one step")]
    fig.legend(handles=handles, fontsize="small", loc="upper left",
               bbox_to_anchor=(0.01, base.MARGINS["top"]))
    return base.save_figure(fig, out)


def gif_trajectory(traj: pd.DataFrame, out: Path, *, box: float) -> Path:
    """An animated GIF of the same run, one frame per printed state, trails behind.

    Drawn with PIL directly: a matplotlib draw per frame cost seconds for a handful of dots.
    """
    ids, x, y = _trajectory_arrays(traj)
    states = x.shape[1]
    norm = Normalize(vmin=float(ids.min()), vmax=float(max(ids.max(), ids.min() + 1)))
    rgb = (mpl.colormaps[TRAJECTORY_CMAP](norm(ids))[:, :3] * 255).round().astype(int)
    colors = [tuple(int(c) for c in row) for row in rgb]
    trails = [tuple((c + 2 * 255) // 3 for c in color) for color in colors]  # faded to white
    scale = (GIF_PIXELS - 2 * GIF_PAD) / box
    px = GIF_PAD + x * scale
    py = GIF_TITLE_PX + (box - y) * scale  # image rows grow downward, y grows upward
    font = ImageFont.load_default(size=GIF_FONT_PX)
    frames = []
    for s in range(states):
        image = Image.new("RGB", (GIF_PIXELS, GIF_PIXELS + GIF_TITLE_PX - GIF_PAD), "white")
        draw = ImageDraw.Draw(image)
        draw.rectangle([GIF_PAD, GIF_TITLE_PX, GIF_PAD + box * scale, GIF_TITLE_PX + box * scale],
                       outline="black", width=2)
        for p in range(len(ids)):
            if s:
                points = list(zip(px[p, : s + 1], py[p, : s + 1], strict=True))
                draw.line(points, fill=trails[p], width=1)
            cx, cy, rad = px[p, s], py[p, s], GIF_DOT_PX
            draw.ellipse([cx - rad, cy - rad, cx + rad, cy + rad], fill=colors[p],
                         outline="black")
        draw.text((GIF_PAD, GIF_PAD // 2), f"step {s} of {states - 1}", fill="black", font=font)
        frames.append(image.quantize(colors=GIF_COLORS))

    def write(handle: IO[bytes]) -> None:
        frames[0].save(handle, format="GIF", save_all=True, append_images=frames[1:],
                       duration=GIF_FRAME_MS, loop=0)

    return atomic.atomic_write(out.with_name(f"{out.name}.gif"), write)
