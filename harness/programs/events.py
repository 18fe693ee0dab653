"""What seq did with one particle in one step (the candidate of SPEC section 2 that reproduces
its move, or free motion), and which rule of SPEC section 2 a program's wrong step breaks, read
from the program's own states before and after it: the first check that holds names the rule.
Pure numpy, the SPEC's expressions in its order: it tells a student where to look."""

import math
from dataclasses import dataclass

import numpy as np

# Relative (to the step's motion) size of a change that is no rounding: a wrong rule moves a
# particle by a fraction of its step, rounding by digits far below.
CHANGED_REL = 1e-6
# The share of particles that must keep their positions for a state to be "the one before".
KEPT_SHARE = 0.9
# A candidate reproduces the move when the particle ends this close to seq's state (relative
# to L): a few roundings of the coordinates, never a different event.
MATCH_REL = 1e-9


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
    return f"{'xy'[axis]} = {'L - r' if velocity > 0 else 'r'}"


def wall_time(q: np.ndarray, w: np.ndarray, L: float, r: float) -> tuple[float, list[int]]:
    """SPEC's wall time of one particle and the axes that hit at it (inf, [] for none)."""
    # Two axes, once per particle on the grading path: a scalar loop is several times faster
    # than numpy on arrays of two.
    times = [(L - r - q[a]) / w[a] if w[a] > 0 else (r - q[a]) / w[a] if w[a] < 0 else math.inf
             for a in range(2)]
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
    times = pair_times(before, i, r)
    # (t, 0 pair / 1 wall, partner)
    candidates = [(float(times[j]), 0, int(j)) for j in np.flatnonzero(np.isfinite(times))]
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


def reference_event(before: np.ndarray, successor: np.ndarray, i: int, kind: str,
                    partner: int, t: float, L: float, r: float) -> Event:
    """The reference's event for particle i as an Event, from its `successor` (x, y, vx, vy):
    the walls it hit, and those it then stopped at (its successor on a wall, its velocity
    into it)."""
    p, v = before[i, :2], before[i, 2:]
    walls: tuple[str, ...] = ()
    if kind == "wall":
        _, axes = wall_time(p, v, L, r)
        walls = tuple(wall_name(a, v[a]) for a in axes)
    stopped: tuple[str, ...] = ()
    if kind != "free":
        end, w = successor[:2], successor[2:]
        stopped = tuple(wall_name(a, w[a]) for a in range(2)
                        if (w[a] > 0 and end[a] == L - r) or (w[a] < 0 and end[a] == r))
    return Event(kind, t, partner if kind == "pair" else None, walls, stopped)


def broken_rule(before: np.ndarray, after: np.ndarray, i: int, event: Event,
                reference: np.ndarray, partners: np.ndarray, L: float, r: float) -> str | None:
    """The rule particle i's move from `before` to `after` ((n, 4) program states) breaks,
    given the reference's event for it, its successor `reference` (x, y, vx, vy) and every
    particle's partner in the reference's step (-1: none)."""
    scale = max(L, float(np.max(np.abs(before[:, 2:])))) * CHANGED_REL
    p1, v0, v1 = after[i, :2], before[i, 2:], after[i, 2:]
    outside = [f"{'xy'[a]} = {p1[a]:.10g}" for a in range(2)
               if p1[a] < r - scale or p1[a] > L - r + scale]
    if outside:
        return f"a disc outside the box after the step ({', '.join(outside)}; [r, L - r] = " \
               f"[{r:g}, {L - r:g}])"
    kept = np.all(np.abs(after[:, :2] - before[:, :2]) <= scale, axis=1)
    if np.mean(kept) >= KEPT_SHARE:
        if np.all(np.abs(after[:, 2:] - before[:, 2:]) <= scale):
            return ("each particle moves once a step: this state is the one before (a step "
                    "missing, or a state printed twice)")
        return ("the positions printed are those before the step, with the velocities after it")
    changed = np.any(np.abs(after[:, 2:] - before[:, 2:]) > scale, axis=1)
    mine = seq_event(before, after, i, L, r)  # the program's move as one SPEC candidate
    if mine is not None and (mine.kind, mine.partner) != (event.kind, event.partner):
        other = mine.partner
        if other is not None and partners[other] not in (-1, i):
            return _twice(other, int(partners[other]), i)
        if mine.kind == "free":
            return f"the collision the rules accept ({event.describe()}) is ignored"
        if math.isclose(mine.t, event.t, rel_tol=1e-12, abs_tol=1e-15):
            return (f"the tie order: at t = {event.t:.6g} it took {mine.describe()} where the "
                    f"rules take {event.describe()} (pair before wall, then smaller i, j)")
        return f"the walk's order: it took {mine.describe()} where the rules take " \
               f"{event.describe()} (the earliest free candidate first)"
    # A pair collision of the program's: i and the reference's partner, or whoever else
    # changed velocity next to it.
    if event.kind == "pair" and event.partner is not None:
        rule = _pair_rule(before, after, i, event.partner, event.t, changed, scale, r)
        if rule:
            return rule
    if event.kind == "wall" and np.allclose(v1, v0, atol=scale):
        return f"a wall met in the step is ignored (the rules: {event.describe()})"
    if event.kind == "wall" and len(event.walls) == 2 and np.count_nonzero(
            np.abs(v1 + v0) <= scale) == 1:
        return f"a corner reverses both velocity components (the rules: {event.describe()})"
    if event.stopped and np.allclose(v1, reference[2:], atol=scale):
        return ("a disc meeting a wall after its collision stops there for the rest of the "
                f"step (the rules: {event.describe()})")
    if event.kind == "free" and changed[i]:
        for m in np.flatnonzero(np.isfinite(pair_times(before, i, r))):
            if partners[m] not in (-1, i) and changed[m]:
                return _twice(int(m), int(partners[m]), i)
        return "a particle with no collision in the step changed its velocity"
    if event.kind == "free" and not changed[i]:
        return "a particle with no collision moves by its velocity (x += vx, y += vy)"
    return None


def _twice(m: int, first: int, i: int) -> str:
    return (f"particle {m} takes part in two collisions in one step: with {first}, which the "
            f"rules accept first, and with {i}")


def _pair_rule(before: np.ndarray, after: np.ndarray, i: int, j: int, t: float,
               changed: np.ndarray, scale: float, r: float) -> str | None:
    dv_i, dv_j = after[i, 2:] - before[i, 2:], after[j, 2:] - before[j, 2:]
    if np.all(np.abs(dv_i + dv_j) <= scale):
        e0 = float(before[i, 2:] @ before[i, 2:] + before[j, 2:] @ before[j, 2:])
        e1 = float(after[i, 2:] @ after[i, 2:] + after[j, 2:] @ after[j, 2:])
        if abs(e1 - e0) > scale * max(1.0, math.sqrt(e0)):
            return (f"the collision of {i} and {j} does not conserve their speed (kinetic energy"
                    f" {e0:.6g} before, {e1:.6g} after)")
        pi = before[i, :2] + t * before[i, 2:]
        pj = before[j, :2] + t * before[j, 2:]
        normal = (pj - pi) / max(float(np.hypot(*(pj - pi))), 1e-300)
        size = float(np.hypot(*dv_i))
        if size > scale and abs(float(dv_i @ normal)) < size * (1 - 1e-6):
            angle = math.degrees(math.acos(min(1.0, abs(float(dv_i @ normal)) / size)))
            return (f"the collision of {i} and {j} changes the velocities {angle:.3g} degrees "
                    "off the line of centres at contact (only the normal components swap)")
        return None
    # Momentum not conserved by the pair: a third particle in it?
    near = np.flatnonzero(changed)
    near = near[(near != i) & (near != j)]
    for k in near:
        for a, b in ((i, j), (j, i)):
            if np.all(np.abs(after[a, 2:] - before[a, 2:] + after[b, 2:] - before[b, 2:]
                             + after[k, 2:] - before[k, 2:]) <= scale * 10):
                return (f"particle {a} takes part in two collisions in one step (with {b} and "
                        f"{k}: their velocity changes sum to zero only together)")
    return (f"the collision of {i} and {j} does not conserve their momentum (velocity changes "
            f"({dv_i[0]:.6g}, {dv_i[1]:.6g}) and ({dv_j[0]:.6g}, {dv_j[1]:.6g}))")
