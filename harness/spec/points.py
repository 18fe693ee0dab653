"""A config's grid of points: every combination of its axes (scene keys, threads, ranks)."""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping

from harness.errors import config_error
from harness.spec.config import Config

PARALLEL_AXES = ("threads", "ranks")  # the axes that say how a scene is run, not what it is


def scene_key(point: Mapping[str, object]) -> tuple[tuple[str, str], ...]:
    """What makes a point's scene: every axis but threads and ranks."""
    return tuple(sorted((k, str(v)) for k, v in point.items() if k not in PARALLEL_AXES))


def axes(config: Config) -> list[tuple[str, tuple[object, ...]]]:
    """The config's axes, in order: its scene's keys, threads, ranks."""
    return [*config.scene.axes, ("threads", config.threads), ("ranks", config.ranks)]


def count_points(config: Config) -> int:
    """How many points expand_points gives, without expanding them: the product of the axes'
    lengths, a zipped group counting once."""
    listed = axes(config)
    zipped = [len(v) for k, v in listed if k in config.zip_keys]
    return max(zipped, default=1) * math.prod(len(v) for k, v in listed
                                              if k not in config.zip_keys)


def expand_points(config: Config) -> list[dict[str, object]]:
    """Every combination of the axes (scene keys, threads, ranks), in config order.

    Axes in `config.zip_keys` advance together (they must have equal lengths); that group
    and every other axis combine as a cross product.
    """
    listed = axes(config)
    zipped = [(k, v) for k, v in listed if k in config.zip_keys]
    lengths = {len(v) for _, v in zipped}
    if len(lengths) > 1:
        got = ", ".join(f"{k}: {len(v)}" for k, v in zipped)
        raise config_error(config.source, "combine", "lists of equal length to zip",
                           f"lengths {got}")
    groups: list[tuple[tuple[str, ...], list[tuple[object, ...]]]] = []
    for key, values in listed:
        if key not in config.zip_keys:
            groups.append(((key,), [(v,) for v in values]))
        elif key == zipped[0][0]:  # the zipped group, where its first axis is
            groups.append((tuple(k for k, _ in zipped),
                           list(zip(*(v for _, v in zipped), strict=True))))
    names = [key for keys, _ in groups for key in keys]
    return [dict(zip(names, itertools.chain.from_iterable(combo), strict=True))
            for combo in itertools.product(*(rows for _, rows in groups))]
