"""What a config would build, counted before anything is built: its cells, and the memory its
scenes take where they list their particles (a generator's scene, a program's input). A config
past the limits is refused at load time with the numbers, not after minutes of building."""

from __future__ import annotations

import contextlib
from pathlib import Path

import psutil

from harness.errors import HarnessError
from harness.spec import scenes
from harness.spec.config import Config, count_points, expand_points, scene_key

# Peak memory of building one listed particle (a generator's tuple and its text row, or
# with_every_particle's drawn particle): measured 460 to 620 bytes at 10^5 particles
# (tracemalloc); rounded up.
LISTED_PARTICLE_BYTES = 640
# A scene file is held as text and split into tokens: about this many times its size.
FILE_TEXT_FACTOR = 8
# How much of a scene file the estimate reads for its N.
FILE_HEAD_BYTES = 4096
GIB = 2**30


def check_cells(config: Config, max_cells: int) -> None:
    """A config error when the config plans more than max_cells cells, counted before
    exclusion: points x variants x builds x schedules."""
    points, schedules = count_points(config), max(1, len(config.schedules))
    cells = points * len(config.variants) * len(config.builds) * schedules
    if cells > max_cells:
        raise HarnessError(f"{config.source}: key 'scene': {cells} cells ({points} points x "
                           f"{len(config.variants)} variants x {len(config.builds)} builds x "
                           f"{schedules} schedules), more than {max_cells} (run --max-cells N "
                           "to allow more)")


def _file_n(path: Path) -> int:
    """N from a scene file's first bytes; 0 where it cannot be read (the load says why)."""
    try:
        with path.open("rb") as f:
            head = f.read(FILE_HEAD_BYTES).decode("utf-8", errors="replace")
        return scenes.parse_int(head.split(maxsplit=1)[0])
    except (OSError, ValueError, IndexError):
        return 0


def scene_bytes(config: Config) -> tuple[int, int, int]:
    """An estimate of the memory the config's scenes take when planned: bytes, the particles
    they list, their distinct points."""
    total = listed = 0
    seen: set[tuple[tuple[str, str], ...]] = set()
    for point in expand_points(config):
        key = scene_key(point)
        if key in seen:
            continue
        seen.add(key)
        n = 0
        if config.scene.kind == "generator":
            name = str(point.get("generator", config.scene.generator))
            n = int(str(point.get("n", scenes.REGISTRY.get(name).defaults.get("n", 0))))
        elif config.scene.kind == "file":
            path = Path(str(point["file"]))
            with contextlib.suppress(OSError):  # the load says why it cannot be read
                total += path.stat().st_size * FILE_TEXT_FACTOR
            n = _file_n(path) if config.lists_particles else 0
        elif config.lists_particles:
            n = int(str(point["n"]))
        listed += max(0, n)
    return total + listed * LISTED_PARTICLE_BYTES, listed, len(seen)


def check_memory(config: Config) -> None:
    """A config error when its scenes would take more than this machine's free memory."""
    need, listed, points = scene_bytes(config)
    free = psutil.virtual_memory().available
    if need > free:
        raise HarnessError(f"{config.source}: key 'scene': its scenes need about "
                           f"{need / GIB:.1f} GiB ({listed} listed particles over {points} "
                           f"scene points, {LISTED_PARTICLE_BYTES} bytes each), more than this "
                           f"machine's {free / GIB:.1f} GiB of free memory")
