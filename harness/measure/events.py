"""What seq did with one particle in one step, from the states before and after it: the
candidate of SPEC section 2 that reproduces its move (a pair collision and its partner, a wall
and which, and whether it then stopped at a wall), or free motion. Pure numpy, the SPEC's
expressions in its order; used to tell a student where to look when a program first leaves
seq's trajectory (harness.measure.agreement)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

# A candidate reproduces the move when the particle ends this close to seq's state (relative
# to L): a few roundings of the coordinates, never a different event.
MATCH_REL = 1e-9
AXES = ("x", "y")


@dataclass(frozen=True)
class Event:
    kind: str  # "pair", "wall" or "free"
    t: float = 0.0
    partner: int | None = None
    walls: tuple[str, ...] = ()  # e.g. ("x = L - r",)
    stopped: tuple[str, ...] = ()  # the walls it stopped at after its collision

    def describe(self) -> str:
        if self.kind == "free":
            return "moved freely (no collision)"
        if self.kind == "pair":
            text = f"collided with particle {self.partner} at t = {self.t:.6g}"
        else:
            where = " and ".join(self.walls)
            text = (f"hit the corner {where}" if len(self.walls) > 1 else f"hit the wall {where}")
            text += f" at t = {self.t:.6g}"
        if self.stopped:
            text += f", then stopped at {' and '.join(self.stopped)} for the rest of the step"
        return text


def wall_name(axis: int, velocity: float) -> str:
    return f"{AXES[axis]} = {'L - r' if velocity > 0 else 'r'}"


def wall_time(q: np.ndarray, w: np.ndarray, L: float, r: float) -> tuple[float, list[int]]:
    """SPEC's wall time of one particle and the axes that hit at it (inf, [] for none)."""
    times = []
    for axis in range(2):
        if w[axis] > 0:
            times.append((L - r - q[axis]) / w[axis])
        elif w[axis] < 0:
            times.append((r - q[axis]) / w[axis])
        else:
            times.append(math.inf)
    tw = min(times)
    return tw, [axis for axis in range(2) if times[axis] == tw and math.isfinite(tw)]


def _finish(p: np.ndarray, v: np.ndarray, rest: float, L: float,
            r: float) -> tuple[np.ndarray, tuple[str, ...]]:
    """finish(rest): a wall met after the collision stops the particle there."""
    tw, axes = wall_time(p, v, L, r)
    tw = max(tw, 0.0)
    if tw < rest:
        p = p + tw * v
        for axis in axes:
            p[axis] = L - r if v[axis] > 0 else r
        return p, tuple(wall_name(a, v[a]) for a in axes)
    return p + rest * v, ()


def pair_times(state: np.ndarray, i: int, r: float) -> np.ndarray:
    """SPEC's pair time of i with every particle (inf where there is no candidate)."""
    x, y, vx, vy = (state[:, k] for k in range(4))
    with np.errstate(all="ignore"):
        dx, dy = x - x[i], y - y[i]
        ddx, ddy = vx - vx[i], vy - vy[i]
        b = dx * ddx + dy * ddy
        d = 2 * r
        c = (dx * dx + dy * dy) - d * d
        a = ddx * ddx + ddy * ddy
        cross = dx * ddy - dy * ddx
        disc = d * d * a - cross * cross
        t = c / (-b + np.sqrt(disc))
    ok = (b < 0) & (c >= 0) & (disc >= 0) & (t <= 1)
    ok[i] = False
    return np.where(ok, t, np.inf)


def seq_event(before: np.ndarray, after: np.ndarray, i: int, L: float, r: float) -> Event | None:
    """The event of particle i in the step from `before` to `after` ((n, 4) arrays of x y vx
    vy, seq's states), or None when no candidate reproduces its move."""
    tolerance = MATCH_REL * L
    target = after[i]

    def matches(p: np.ndarray, v: np.ndarray) -> bool:
        p = np.clip(p, r, L - r)
        return bool(np.all(np.abs(p - target[:2]) <= tolerance)
                    and np.all(np.abs(v - target[2:]) <= tolerance))

    p0, v0 = before[i, :2].astype(float), before[i, 2:].astype(float)
    candidates: list[tuple[float, int, int]] = []  # (t, 0 pair / 1 wall, partner)
    times = pair_times(before, i, r)
    for j in np.flatnonzero(np.isfinite(times)):
        candidates.append((float(times[j]), 0, int(j)))
    tw, axes = wall_time(p0, v0, L, r)
    if tw <= 1:
        candidates.append((tw, 1, -1))
    for t, kind, j in sorted(candidates):
        p = p0 + t * v0
        if kind == 0:
            pj = before[j, :2] + t * before[j, 2:]
            normal = pj - p
            normal = normal / math.hypot(normal[0], normal[1])
            ui, uj = float(v0 @ normal), float(before[j, 2:] @ normal)
            v = v0 + (uj - ui) * normal
            end, stopped = _finish(p, v, 1 - t, L, r)
            if matches(end, v):
                return Event("pair", t, j, stopped=stopped)
        else:
            v = v0.copy()
            for axis in axes:
                p[axis] = L - r if v0[axis] > 0 else r
                v[axis] = -v0[axis]
            end, stopped = _finish(p, v, 1 - t, L, r)
            if matches(end, v):
                return Event("wall", t, walls=tuple(wall_name(a, v0[a]) for a in axes),
                             stopped=stopped)
    if matches(p0 + v0, v0):
        return Event("free")
    return None
