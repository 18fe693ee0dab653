"""Which rule of SPEC section 2 a program's wrong step breaks, read from the program's own states
before and after the step (pure numpy; harness.measure.steps finds the step). The first
check that holds names the rule; None when none does (the values then speak for themselves).
"""

from __future__ import annotations

import math

import numpy as np

from harness.measure.events import Event, pair_times, seq_event, wall_name, wall_time

# Relative (to the step's motion) size of a change that is no rounding: a wrong rule moves a
# particle by a fraction of its step, rounding by digits far below.
CHANGED_REL = 1e-6
# The share of particles that must keep their positions for a state to be "the one before".
KEPT_SHARE = 0.9


def reference_event(before: np.ndarray, successor: np.ndarray, i: int, kind: str,
                    partner: int, t: float, L: float, r: float) -> Event:
    """The reference's event for particle i as an Event: the walls it hit, and those it then
    stopped at (its successor on a wall, its velocity into it)."""
    p, v = before[i, :2], before[i, 2:]
    walls: tuple[str, ...] = ()
    if kind == "wall":
        _, axes = wall_time(p, v, L, r)
        walls = tuple(wall_name(a, v[a]) for a in axes)
    stopped: tuple[str, ...] = ()
    if kind != "free":
        end, w = successor[i, :2], successor[i, 2:]
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
            return (f"particle {other} takes part in two collisions in one step: with "
                    f"{partners[other]}, which the rules accept first, and with {i}")
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
                return (f"particle {m} takes part in two collisions in one step: with "
                        f"{partners[m]}, which the rules accept first, and with {i}")
        return "a particle with no collision in the step changed its velocity"
    if event.kind == "free" and not changed[i]:
        return "a particle with no collision moves by its velocity (x += vx, y += vy)"
    return None


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
