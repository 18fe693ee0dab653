#!/usr/bin/env python3
"""A student's hard-disc simulation, written from the assignment, not from this project.

    sim.py THREADS [--slip] < INPUT

It reads the input on stdin, takes the thread count as its first argument (and ignores it:
it is serial), draws unlisted particles with its own generator, prints the state after every
step (0 included) with six decimals in print mode, and the initial and final states in perf
mode. With --slip it forgets one rule: a particle that meets a wall after its collision in a
step is not stopped there, it slides on (and is clamped into the box).
"""

import math
import random
import sys


def wall_time(x, y, vx, vy, L, r):
    times = []
    for q, w in ((x, vx), (y, vy)):
        if w > 0:
            times.append((L - r - q) / w)
        elif w < 0:
            times.append((r - q) / w)
        else:
            times.append(math.inf)
    t = min(times)
    return t, [axis for axis in (0, 1) if times[axis] == t and t != math.inf]


def pair_time(a, b, r):
    dx, dy = b[0] - a[0], b[1] - a[1]
    dvx, dvy = b[2] - a[2], b[3] - a[3]
    dot = dx * dvx + dy * dvy
    if dot >= 0:
        return None
    gap = (dx * dx + dy * dy) - (2 * r) * (2 * r)
    if gap < 0:
        return None
    speed2 = dvx * dvx + dvy * dvy
    cross = dx * dvy - dy * dvx
    disc = (2 * r) * (2 * r) * speed2 - cross * cross
    if disc < 0:
        return None
    return gap / (-dot + math.sqrt(disc))


def finish(p, rest, L, r, slip):
    t, axes = wall_time(p[0], p[1], p[2], p[3], L, r)
    t = max(t, 0.0)
    if t < rest and not slip:
        p[0] += t * p[2]
        p[1] += t * p[3]
        for axis in axes:
            p[axis] = L - r if p[axis + 2] > 0 else r
    else:
        p[0] += rest * p[2]
        p[1] += rest * p[3]


def step(ps, L, r, slip, counts):
    found = []
    for i, p in enumerate(ps):
        t, axes = wall_time(p[0], p[1], p[2], p[3], L, r)
        if t <= 1:
            found.append((t, 1, i, -1, axes))
        for j in range(i + 1, len(ps)):
            t = pair_time(p, ps[j], r)
            if t is not None and t <= 1:
                found.append((t, 0, i, j, None))
    found.sort(key=lambda c: c[:4])
    done = [False] * len(ps)
    for t, kind, i, j, axes in found:
        if done[i] or (kind == 0 and done[j]):
            continue
        a = ps[i]
        if kind == 0:
            b = ps[j]
            done[i] = done[j] = True
            for q in (a, b):
                q[0] += t * q[2]
                q[1] += t * q[3]
            dx, dy = b[0] - a[0], b[1] - a[1]
            length = math.sqrt(dx * dx + dy * dy)
            nx, ny = dx / length, dy / length
            ua, ub = a[2] * nx + a[3] * ny, b[2] * nx + b[3] * ny
            a[2] += (ub - ua) * nx
            a[3] += (ub - ua) * ny
            b[2] += (ua - ub) * nx
            b[3] += (ua - ub) * ny
            counts[i][0] += 1
            counts[j][0] += 1
            finish(a, 1 - t, L, r, slip)
            finish(b, 1 - t, L, r, slip)
        else:
            done[i] = True
            a[0] += t * a[2]
            a[1] += t * a[3]
            for axis in axes:
                a[axis] = L - r if a[axis + 2] > 0 else r
                a[axis + 2] = -a[axis + 2]
            counts[i][1] += 1
            finish(a, 1 - t, L, r, slip)
    for i, p in enumerate(ps):
        if not done[i]:
            p[0] += p[2]
            p[1] += p[3]
        p[0] = min(max(p[0], r), L - r)
        p[1] = min(max(p[1], r), L - r)


def main():
    threads = int(sys.argv[1])
    slip = "--slip" in sys.argv[2:]
    assert threads >= 1
    words = sys.stdin.read().split()
    n, L, r, steps, mode = int(words[0]), float(words[1]), float(words[2]), int(words[3]), words[4]
    ps = [None] * n
    rest = words[5:]
    for k in range(0, len(rest), 5):
        ps[int(rest[k])] = [float(v) for v in rest[k + 1:k + 5]]
    own = random.Random(2024)
    for i in range(n):
        if ps[i] is None:
            ps[i] = [own.uniform(r, L - r), own.uniform(r, L - r), own.uniform(-1, 1),
                     own.uniform(-1, 1)]
    counts = [[0, 0] for _ in range(n)]
    out = []
    for s in range(steps):
        if mode == "print" or s == 0:
            out.extend(f"{s} {i} {p[0]:.6f} {p[1]:.6f} {p[2]:.6f} {p[3]:.6f}"
                       for i, p in enumerate(ps))
        step(ps, L, r, slip, counts)
    out.extend(f"{steps} {i} {p[0]:.6f} {p[1]:.6f} {p[2]:.6f} {p[3]:.6f} {c[0]} {c[1]}"
               for i, (p, c) in enumerate(zip(ps, counts, strict=True)))
    print("\n".join(out))


main()
