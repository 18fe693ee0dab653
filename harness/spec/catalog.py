"""The stiff and extreme scene catalog: named scenes that stress one rule or one rounding each.
Every entry is a generator taking `steps` (its default: enough for its event, and the runs
after it) and `mode`; `catalog()` maps each name to the sentence saying what it stresses.

Geometry is chosen so that the critical quantities are exact in binary (contact at exactly
t = 1, a discriminant of exactly 0, bit-identical tie times), unless the point of the scene is
that rounding decides (45-degree touching, 1e-13 from a wall, grazing at L = 1e7).
"""

import math
import random
from collections.abc import Sequence

from harness.spec.scenes import REGISTRY, Particle, ScenePoint, generator, make_scene

SMALL_L = 100.0  # the box of the few-disc scenes
MID = SMALL_L / 2
R = 1.0
DIAMETER = 2 * R
HUGE_L = 1e7
GRAZE_APART = 9e5  # centre distance of the far grazing pairs along x
GRAZE_SPEED = 5e5  # each disc of a grazing pair, towards the other
GRAZE_IMPACTS = (0.5, 0.9, 0.999, 0.999999, 1.0, 1.000001)  # impact parameter / 2r
GRAZE_ROW_SPACING = 100.0
HEX_GAP = 1e-9  # gap between hexagonally packed neighbours, relative to r
HEX_SIDE = 7  # discs per row and rows
HEX_SPEED = 1e-3  # speed of the packed discs (relative to r per step)
HEX_SEED = 12345
DENSE_N = 400


def scene(name: str, default_steps: int, doc: str, particles: Sequence[Particle],
          L: float = SMALL_L, n: int | None = None) -> None:
    """Register generator `name`: the given particles (n > their number: the rest drawn by
    the binaries) in a box of side L, `default_steps` steps unless a config says; its
    docstring `doc` is the catalog's sentence."""
    listed = list(particles)

    def generate(steps: int = default_steps, mode: str = "perf") -> ScenePoint:
        return make_scene(L, R, steps, mode, listed, n=n)

    generate.__doc__ = doc
    generator(name)(generate)


# --- collisions and ties ------------------------------------------------------------------

scene("contact_t1", 4, """Two discs whose contact time is exactly 1.0 (c = 32, -b + sqrt(disc) =
      32): the `t <= 1` boundary of a step.""",
      [(MID - 3, MID, 2.0, 0.0), (MID + 3, MID, -2.0, 0.0)])
scene("tie4", 4, """Four discs on a square's corners flying at its centre: four pair contacts
      with bit-identical times, resolved only by the (i, j) tie-break.""",
      [(MID - 5, MID - 5, 4.5, 4.5), (MID + 5, MID - 5, -4.5, 4.5),
       (MID - 5, MID + 5, 4.5, -4.5), (MID + 5, MID + 5, -4.5, -4.5)])
scene("tie3", 4, """One disc at rest between two that approach it symmetrically: two contacts
      at the same time share the middle disc, so one must pass through it.""",
      [(MID - 10, MID, 9.0, 0.0), (MID, MID, 0.0, 0.0), (MID + 10, MID, -9.0, 0.0)])
scene("cradle", 6, """Newton's cradle: a striker and a row of discs touching exactly (c == 0),
      so contacts at t = 0 propagate one disc per step.""",
      [(MID - 6, MID, 5.0, 0.0), *((MID + k * DIAMETER, MID, 0.0, 0.0) for k in range(5))])
scene("tangent", 3, """A grazing pair whose discriminant is exactly 0 (cross^2 == (2r)^2 a):
      the edge between a hit and a miss, and the worst-conditioned contact time.""",
      [(MID, MID, 0.0, 0.0), (MID + 2.5, MID + 2.0, -5.0, 0.0)])
scene("touch_axis", 3, """Two discs touching at the start along x (distance exactly 2r) and
      approaching: a collision at t = 0.""",
      [(MID, MID, 1.0, 0.0), (MID + DIAMETER, MID, -1.0, 0.0)])
scene("touch_diagonal", 3, """Two discs touching at the start at 45 degrees: 2r/sqrt(2) is
      inexact, so rounding of c decides between a collision at t = 0 and passing through as
      overlapping.""",
      [(MID, MID, 1.0, 1.0), (MID + DIAMETER / math.sqrt(2.0),
                              MID + DIAMETER / math.sqrt(2.0), -1.0, -1.0)])
scene("overlap", 3, """Two discs overlapping at the start (centres r apart) and approaching:
      c < 0, so they pass through each other (seed assumption 1).""",
      [(MID, MID, 1.0, 0.5), (MID + R, MID, -1.0, -0.5)])
scene("underflow", 3, """A pair with equal velocities (D = 0, b = 0) and a pair approaching at
      |D| = 1e-170, whose a = |D|^2 underflows to 0: the root must not divide by a.""",
      [(20.0, 20.0, 1.0, 1.0), (20.0 + 3.0, 20.0, 1.0, 1.0),
       (60.0, 60.0, 0.0, 0.0), (60.0 + DIAMETER, 60.0, -1e-170, 0.0)])

# --- walls --------------------------------------------------------------------------------

scene("wall_outward", 3, """A disc exactly on the wall (x = L - r) moving outward: wall time 0,
      bounce at t = 0.""",
      [(SMALL_L - R, MID, 3.0, 0.5)])
scene("wall_near", 3, """A disc 1e-13 inside the wall moving outward: its wall time (~3e-14)
      rounds to about zero, and a float build cannot even represent the gap.""",
      [(SMALL_L - R - 1e-13, MID, 3.0, 0.5)])
scene("near_corner", 4, """A disc 1e-12 off the diagonal with vx == vy: the two axis times
      differ in the last bits, so it bounces off one wall and then stops at the other for the
      rest of the step (compare `corner`, the exact corner hit).""",
      [(MID, MID + 1e-12, 20.0, 20.0)])
scene("wall_then_pair", 3, """A disc bounces off a wall and then runs into a disc within the
      same step: it has had its one collision, so they end the step overlapping and then pass
      through.""",
      [(SMALL_L - R - 1.5, MID, 4.0, 0.0), (SMALL_L - R - 4.4, MID, 0.0, 0.0)])

# --- scales -------------------------------------------------------------------------------


def _grazing_pairs() -> list[Particle]:
    particles: list[Particle] = []
    x0 = HUGE_L / 2 - GRAZE_APART / 2
    for k, impact in enumerate(GRAZE_IMPACTS):
        y = HUGE_L / 2 + (k - len(GRAZE_IMPACTS) / 2) * GRAZE_ROW_SPACING
        particles.append((x0, y, GRAZE_SPEED, 0.0))
        particles.append((x0 + GRAZE_APART, y + impact * DIAMETER, -GRAZE_SPEED, 0.0))
    return particles


def _hex_packed() -> list[Particle]:
    rng = random.Random(HEX_SEED)
    spacing = DIAMETER * (1 + HEX_GAP)
    row_height = spacing * math.sqrt(3.0) / 2
    particles: list[Particle] = []
    for row in range(HEX_SIDE):
        for col in range(HEX_SIDE):
            x = MID + col * spacing + (spacing / 2 if row % 2 else 0.0)
            y = MID + row * row_height
            angle = rng.uniform(0.0, 2 * math.pi)
            particles.append((x, y, HEX_SPEED * math.cos(angle), HEX_SPEED * math.sin(angle)))
    return particles


TIGHT_L = DIAMETER + 1e-9
TIGHT_HI = TIGHT_L - R  # computed as the core computes it, so the disc is exactly on the wall
FAST_V = 3.7 * SMALL_L

scene("far_grazing", 2, """L = 1e7, r = 1: pairs 9e5 apart closing at 1e6 per step with impact
      parameters from 0.5 to 1.000001 diameters; b*b - a*c cancels ~24 digits here (the
      textbook formula's failure).""",
      _grazing_pairs(), L=HUGE_L)
scene("tight_box", 4, """2r = L - 1e-9: the centres live in a 1e-9 square, every step hits walls
      at times ~1e-10, and the two discs always overlap; a float build rounds the box to
      exactly 2r.""",
      [(R, R, 3.0, 2.0), (TIGHT_HI, R + (TIGHT_HI - R) / 2, -1.0, 0.5)], L=TIGHT_L)
scene("hex_gap", 3, """Hexagonal packing with gaps of 1e-9 r and small random velocities: every
      disc has up to six contacts within ~1e-6 of a step, and which one wins is decided near
      the rounding level.""",
      _hex_packed(), L=2 * SMALL_L)
scene("faster_than_box", 4, """Discs moving 3.7 L per step: every step is a wall bounce and a
      stop at the opposite wall; nothing may tunnel out of the box.""",
      [(30.0, 40.0, FAST_V, 0.3 * FAST_V), (70.0, 20.0, -0.6 * FAST_V, FAST_V),
       (50.0, 80.0, -FAST_V, -FAST_V)])

# --- sizes --------------------------------------------------------------------------------

scene("empty", 3, "N = 0: no particles at all.", [])
scene("single", 5, "N = 1: one disc bouncing around, no pairs.", [(MID, 30.0, 17.0, -23.0)])
scene("no_steps", 0, """S = 0 (by default): the output is the input state, with zero collision
      counts.""",
      [(MID, MID, 1.0, 2.0), (MID + 10, MID, -1.0, 0.0)])
scene("dense30", 5, """400 generated discs at 30% area packing (overlaps allowed), speeds 8-16 r
      per step: many contacts per disc per step, most of them lost to the one-collision
      rule.""",
      [], L=math.sqrt(DENSE_N * math.pi * R * R / 0.3), n=DENSE_N)
scene("dense50", 5, """400 generated discs at 50% area packing: as dense30, with overlaps at the
      start the rule, not the exception.""",
      [], L=math.sqrt(DENSE_N * math.pi * R * R / 0.5), n=DENSE_N)

# Catalog order: head_on and corner are generators of harness.spec.scenes.
CATALOG_NAMES: tuple[str, ...] = (
    "head_on", "contact_t1", "tie4", "tie3", "cradle", "tangent", "touch_axis",
    "touch_diagonal", "overlap", "underflow", "wall_outward", "wall_near", "corner",
    "near_corner", "wall_then_pair", "far_grazing", "tight_box", "hex_gap",
    "faster_than_box", "empty", "single", "no_steps", "dense30", "dense50",
)


def catalog() -> dict[str, str]:
    """Each catalog scene's name and what it stresses (its generator's docstring)."""
    return {name: " ".join(REGISTRY[name].doc.split()) for name in CATALOG_NAMES}
