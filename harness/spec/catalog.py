"""The stiff and extreme scene catalog: named scenes that stress one rule or one rounding each.

Every entry is a generator registered with `@generator` (so a config names it as
`scene: {generator: NAME}`, or sweeps several with `scene: {generator: [A, B, ...]}`), and
`CATALOG` maps each name to the sentence saying what it stresses, in catalog order.
Every catalog generator takes `steps` and `mode`, so a config can set those for all of them;
each has its own default step count (enough for its event, and the runs after it).

Geometry is chosen so that the critical quantities are exact in binary (contact at exactly
t = 1, a discriminant of exactly 0, bit-identical tie times), unless the point of the scene is
that rounding decides (45-degree touching, 1e-13 from a wall, grazing at L = 1e7).
"""

from __future__ import annotations

import math
import random

from harness.spec.scenes import REGISTRY, GeneratedScene, Particle, generator, make_scene

SMALL_L = 100.0  # the box of the few-disc scenes
MID = SMALL_L / 2
R = 1.0
DIAMETER = 2 * R
NEAR_WALL_GAP = 1e-13  # "inside the wall" distance: its wall time rounds to about zero
NEAR_CORNER_OFFSET = 1e-12  # off the diagonal: the two axis times differ in the last bits
UNDERFLOW_SPEED = 1e-170  # |D|^2 = 1e-340 underflows to 0 in double
HUGE_L = 1e7
GRAZE_APART = 9e5  # centre distance of the far grazing pairs along x
GRAZE_SPEED = 5e5  # each disc of a grazing pair, towards the other
GRAZE_IMPACTS = (0.5, 0.9, 0.999, 0.999999, 1.0, 1.000001)  # impact parameter / 2r
GRAZE_ROW_SPACING = 100.0
TIGHT_SLACK = 1e-9  # L - 2r of the box barely larger than a disc
HEX_GAP = 1e-9  # gap between hexagonally packed neighbours, relative to r
HEX_SIDE = 7  # discs per row and rows
HEX_SPEED = 1e-3  # speed of the packed discs (relative to r per step)
HEX_SEED = 12345
FAST_FACTOR = 3.7  # speed in units of L per step
DENSE_N = 400
DENSE_PACKING = (0.3, 0.5)  # area fraction N*pi*r^2 / L^2


def _scene(particles: list[Particle], steps: int, mode: str, L: float = SMALL_L,
           n: int | None = None) -> GeneratedScene:
    return make_scene(L, R, steps, mode, particles, n=n)


# --- collisions and ties ------------------------------------------------------------------


@generator("contact_t1")
def contact_t1(steps: int = 4, mode: str = "perf") -> GeneratedScene:
    """Two discs whose contact time is exactly 1.0 (c = 32, -b + sqrt(disc) = 32): the `t <= 1`
    boundary of a step."""
    return _scene([(MID - 3, MID, 2.0, 0.0), (MID + 3, MID, -2.0, 0.0)], steps, mode)


@generator("tie4")
def tie4(steps: int = 4, mode: str = "perf") -> GeneratedScene:
    """Four discs on a square's corners flying at its centre: four pair contacts with
    bit-identical times, resolved only by the (i, j) tie-break."""
    s = 4.5
    particles = [(MID - 5, MID - 5, s, s), (MID + 5, MID - 5, -s, s),
                 (MID - 5, MID + 5, s, -s), (MID + 5, MID + 5, -s, -s)]
    return _scene(particles, steps, mode)


@generator("tie3")
def tie3(steps: int = 4, mode: str = "perf") -> GeneratedScene:
    """One disc at rest between two that approach it symmetrically: two contacts at the same
    time share the middle disc, so one must pass through it."""
    return _scene([(MID - 10, MID, 9.0, 0.0), (MID, MID, 0.0, 0.0), (MID + 10, MID, -9.0, 0.0)],
                  steps, mode)


@generator("cradle")
def cradle(steps: int = 6, mode: str = "perf") -> GeneratedScene:
    """Newton's cradle: a striker and a row of discs touching exactly (c == 0), so contacts at
    t = 0 propagate one disc per step."""
    row = [(MID + k * DIAMETER, MID, 0.0, 0.0) for k in range(5)]
    return _scene([(MID - 6, MID, 5.0, 0.0), *row], steps, mode)


@generator("tangent")
def tangent(steps: int = 3, mode: str = "perf") -> GeneratedScene:
    """A grazing pair whose discriminant is exactly 0 (cross^2 == (2r)^2 a): the edge between a
    hit and a miss, and the worst-conditioned contact time."""
    return _scene([(MID, MID, 0.0, 0.0), (MID + 2.5, MID + 2.0, -5.0, 0.0)], steps, mode)


@generator("touch_axis")
def touch_axis(steps: int = 3, mode: str = "perf") -> GeneratedScene:
    """Two discs touching at the start along x (distance exactly 2r) and approaching: a
    collision at t = 0."""
    return _scene([(MID, MID, 1.0, 0.0), (MID + DIAMETER, MID, -1.0, 0.0)], steps, mode)


@generator("touch_diagonal")
def touch_diagonal(steps: int = 3, mode: str = "perf") -> GeneratedScene:
    """Two discs touching at the start at 45 degrees: 2r/sqrt(2) is inexact, so rounding of c
    decides between a collision at t = 0 and passing through as overlapping."""
    h = DIAMETER / math.sqrt(2.0)
    return _scene([(MID, MID, 1.0, 1.0), (MID + h, MID + h, -1.0, -1.0)], steps, mode)


@generator("overlap")
def overlap(steps: int = 3, mode: str = "perf") -> GeneratedScene:
    """Two discs overlapping at the start (centres r apart) and approaching: c < 0, so they pass
    through each other (seed assumption 1)."""
    return _scene([(MID, MID, 1.0, 0.5), (MID + R, MID, -1.0, -0.5)], steps, mode)


@generator("underflow")
def underflow(steps: int = 3, mode: str = "perf") -> GeneratedScene:
    """A pair with equal velocities (D = 0, b = 0) and a pair approaching at |D| = 1e-170, whose
    a = |D|^2 underflows to 0: the root must not divide by a."""
    particles = [(20.0, 20.0, 1.0, 1.0), (20.0 + 3.0, 20.0, 1.0, 1.0),
                 (60.0, 60.0, 0.0, 0.0), (60.0 + DIAMETER, 60.0, -UNDERFLOW_SPEED, 0.0)]
    return _scene(particles, steps, mode)


# --- walls --------------------------------------------------------------------------------


@generator("wall_outward")
def wall_outward(steps: int = 3, mode: str = "perf") -> GeneratedScene:
    """A disc exactly on the wall (x = L - r) moving outward: wall time 0, bounce at t = 0."""
    return _scene([(SMALL_L - R, MID, 3.0, 0.5)], steps, mode)


@generator("wall_near")
def wall_near(steps: int = 3, mode: str = "perf") -> GeneratedScene:
    """A disc 1e-13 inside the wall moving outward: its wall time (~3e-14) rounds to about
    zero, and a float build cannot even represent the gap."""
    return _scene([(SMALL_L - R - NEAR_WALL_GAP, MID, 3.0, 0.5)], steps, mode)


@generator("near_corner")
def near_corner(steps: int = 4, mode: str = "perf") -> GeneratedScene:
    """A disc 1e-12 off the diagonal with vx == vy: the two axis times differ in the last bits,
    so it bounces off one wall and then stops at the other for the rest of the step (compare
    `corner`, the exact corner hit)."""
    return _scene([(MID, MID + NEAR_CORNER_OFFSET, 20.0, 20.0)], steps, mode)


@generator("wall_then_pair")
def wall_then_pair(steps: int = 3, mode: str = "perf") -> GeneratedScene:
    """A disc bounces off a wall and then runs into a disc within the same step: it has had its
    one collision, so they end the step overlapping and then pass through."""
    return _scene([(SMALL_L - R - 1.5, MID, 4.0, 0.0), (SMALL_L - R - 4.4, MID, 0.0, 0.0)],
                  steps, mode)


# --- scales -------------------------------------------------------------------------------


@generator("far_grazing")
def far_grazing(steps: int = 2, mode: str = "perf") -> GeneratedScene:
    """L = 1e7, r = 1: pairs 9e5 apart closing at 1e6 per step with impact parameters from 0.5
    to 1.000001 diameters; b*b - a*c cancels ~24 digits here (the textbook formula's failure)."""
    particles: list[Particle] = []
    x0 = HUGE_L / 2 - GRAZE_APART / 2
    for k, impact in enumerate(GRAZE_IMPACTS):
        y = HUGE_L / 2 + (k - len(GRAZE_IMPACTS) / 2) * GRAZE_ROW_SPACING
        particles.append((x0, y, GRAZE_SPEED, 0.0))
        particles.append((x0 + GRAZE_APART, y + impact * DIAMETER, -GRAZE_SPEED, 0.0))
    return _scene(particles, steps, mode, L=HUGE_L)


@generator("tight_box")
def tight_box(steps: int = 4, mode: str = "perf") -> GeneratedScene:
    """2r = L - 1e-9: the centres live in a 1e-9 square, every step hits walls at times ~1e-10,
    and the two discs always overlap; a float build rounds the box to exactly 2r."""
    L = DIAMETER + TIGHT_SLACK
    hi = L - R  # computed as the core computes it, so the disc is exactly on the wall
    return _scene([(R, R, 3.0, 2.0), (hi, R + (hi - R) / 2, -1.0, 0.5)], steps, mode, L=L)


@generator("hex_gap")
def hex_gap(steps: int = 3, mode: str = "perf") -> GeneratedScene:
    """Hexagonal packing with gaps of 1e-9 r and small random velocities: every disc has up to six
    contacts within ~1e-6 of a step, and which one wins is decided near the rounding level."""
    rng = random.Random(HEX_SEED)
    spacing = DIAMETER * (1 + HEX_GAP)
    row_height = spacing * math.sqrt(3.0) / 2
    L = 2 * SMALL_L
    particles: list[Particle] = []
    for row in range(HEX_SIDE):
        for col in range(HEX_SIDE):
            x = MID + col * spacing + (spacing / 2 if row % 2 else 0.0)
            y = MID + row * row_height
            angle = rng.uniform(0.0, 2 * math.pi)
            particles.append((x, y, HEX_SPEED * math.cos(angle), HEX_SPEED * math.sin(angle)))
    return _scene(particles, steps, mode, L=L)


@generator("faster_than_box")
def faster_than_box(steps: int = 4, mode: str = "perf") -> GeneratedScene:
    """Discs moving 3.7 L per step: every step is a wall bounce and a stop at the opposite wall;
    nothing may tunnel out of the box."""
    v = FAST_FACTOR * SMALL_L
    particles = [(30.0, 40.0, v, 0.3 * v), (70.0, 20.0, -0.6 * v, v), (50.0, 80.0, -v, -v)]
    return _scene(particles, steps, mode)


# --- sizes --------------------------------------------------------------------------------


@generator("empty")
def empty(steps: int = 3, mode: str = "perf") -> GeneratedScene:
    """N = 0: no particles at all."""
    return _scene([], steps, mode)


@generator("single")
def single(steps: int = 5, mode: str = "perf") -> GeneratedScene:
    """N = 1: one disc bouncing around, no pairs."""
    return _scene([(MID, 30.0, 17.0, -23.0)], steps, mode)


@generator("no_steps")
def no_steps(steps: int = 0, mode: str = "perf") -> GeneratedScene:
    """S = 0 (by default): the output is the input state, with zero collision counts."""
    return _scene([(MID, MID, 1.0, 2.0), (MID + 10, MID, -1.0, 0.0)], steps, mode)


def _dense(packing: float, steps: int, mode: str) -> GeneratedScene:
    L = math.sqrt(DENSE_N * math.pi * R * R / packing)
    return _scene([], steps, mode, L=L, n=DENSE_N)


@generator("dense30")
def dense30(steps: int = 5, mode: str = "perf") -> GeneratedScene:
    """400 generated discs at 30% area packing (overlaps allowed), speeds 8-16 r per step: many
    contacts per disc per step, most of them lost to the one-collision rule."""
    return _dense(DENSE_PACKING[0], steps, mode)


@generator("dense50")
def dense50(steps: int = 5, mode: str = "perf") -> GeneratedScene:
    """400 generated discs at 50% area packing: as dense30, with overlaps at the start the
    rule, not the exception."""
    return _dense(DENSE_PACKING[1], steps, mode)


# Catalog order: head_on and corner are generators of harness.spec.scenes.
CATALOG_NAMES: tuple[str, ...] = (
    "head_on", "contact_t1", "tie4", "tie3", "cradle", "tangent", "touch_axis",
    "touch_diagonal", "overlap", "underflow", "wall_outward", "wall_near", "corner",
    "near_corner", "wall_then_pair", "far_grazing", "tight_box", "hex_gap",
    "faster_than_box", "empty", "single", "no_steps", "dense30", "dense50",
)


def catalog() -> dict[str, str]:
    """Each catalog scene's name and what it stresses (its generator's docstring)."""
    return {name: " ".join(REGISTRY.get(name).doc.split()) for name in CATALOG_NAMES}
