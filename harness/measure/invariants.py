"""The invariants a correct run keeps (SPEC section 7), checked on one print-mode output (pure):

* finite: every printed coordinate and velocity is a finite number;
* in_box: every finite coordinate lies in [r, L - r] (a float build computes the box in float,
  so it gets `BOX_TOLERANCE_F32 * L` of slack; every other build none);
* pcoll_even: the final pcoll sum is even (each pair collision counts for both discs);
* energy: the relative kinetic-energy drift |E_s - E_0| / E_0, over every printed state s,
  stays within `energy_bound` (the justification is in its docstring).
"""

import math
from dataclasses import dataclass

import numpy as np

from harness.spec.builds import DOUBLE_EPS, unit_roundoff
from harness.spec.config import DEFAULT_ENERGY_ULPS
from harness.spec.output import Output, split_states

# L - r and r rounded to float can sit up to ~1.5 ulp(L) outside the double box.
BOX_TOLERANCE_F32 = 2.0**-22
# Reading the energy back: squares rounded in double, summed exactly (fsum), and for the f128
# build velocities rounded to double by %.17g: a few double ulps of the total, at any state.
ENERGY_READ_ULPS = 8.0


@dataclass(frozen=True)
class Invariants:
    finite: bool
    in_box: bool
    pcoll_even: bool
    energy: bool
    energy_drift: float  # |E_S - E_0| / E_0 at the final state
    energy_drift_max: float  # the largest |E_s - E_0| / E_0 over the printed states
    energy_bound: float
    pair_collisions: int  # accepted pair collisions over the run: sum(pcoll) / 2
    box_excess: float  # the farthest a finite coordinate lies outside [r, L - r], / L
    states: int  # printed states, the final block included


def energy_bound(build: str, pair_collisions: int, ulps: float = DEFAULT_ENERGY_ULPS) -> float:
    """The largest relative kinetic-energy drift a correct run of `build` can show.

    Only pair collisions change |v|: a wall bounce negates a component (exact), stopping at a
    wall keeps the velocity, the clamp touches positions only. A pair collision sets
    vi += (uj - ui) n, vj += (ui - uj) n with n = d / |d| computed, so |n|^2 = 1 + delta with
    |delta| <= ~6 eps (two squares, a sum, a square root, a division). In exact arithmetic on
    that n the pair's energy changes by 2 (uj - ui)^2 delta <= 4 E_pair * 6 eps = 24 eps E_pair,
    and rounding the two dot products and four updates adds a few eps E_pair more: about 30 eps
    of E_pair <= E_total per collision, hence k = 32 by default. Errors of successive
    collisions add at most linearly, so the bound is k * eps * P for P collisions (a random walk
    would give ~sqrt(P); the linear bound is the safe one). A float build has eps = 2^-24, a
    double (and the formula builds) 2^-53, __float128 2^-113. Reading the energy back costs a
    few double ulps more (ENERGY_READ_ULPS), even with no collision at all.
    """
    return ulps * unit_roundoff(build) * pair_collisions + ENERGY_READ_ULPS * DOUBLE_EPS


def energies(velocities: list[np.ndarray]) -> np.ndarray:
    """Sum of |v|^2 per state, in a common power-of-two scale so that neither 1e-170 speeds
    underflow nor 1e200 ones overflow (the scale cancels in relative drifts)."""
    finite = [v[np.isfinite(v)] for v in velocities]
    largest = max((float(np.abs(v).max()) for v in finite if v.size), default=0.0)
    scale = 1.0 if largest == 0.0 else math.ldexp(1.0, -math.frexp(largest)[1])
    return np.array([math.fsum(np.square((v * scale).ravel()).tolist())
                     if np.all(np.isfinite(v)) else math.nan for v in velocities],
                    dtype=np.float64)


def energy_drifts(velocities: list[np.ndarray]) -> tuple[float, float]:
    """(final, largest) relative drift |E_s - E_0| / E_0; inf when E_0 = 0 and some E_s is
    not, or when a velocity is not finite."""
    e = energies(velocities)
    if not len(e) or not np.all(np.isfinite(e)):
        return math.inf, math.inf
    zero = e[0] == 0.0
    drift = np.where(e == 0.0, 0.0, math.inf) if zero else np.abs(e - e[0]) / e[0]
    return float(drift[-1]), float(drift.max())


def check(out: Output, L: float, r: float, build: str,
          energy_ulps: float = DEFAULT_ENERGY_ULPS) -> Invariants:
    states = split_states(out)  # the final state at least
    positions = np.concatenate([p for p, _ in states])
    velocities = [v for _, v in states]
    finite = bool(np.all(np.isfinite(positions))
                  and np.all(np.isfinite(np.concatenate(velocities))))
    coords = positions[np.isfinite(positions)]
    tolerance = BOX_TOLERANCE_F32 * L if build == "f32" else 0.0
    excess = (max(0.0, float(r - coords.min()), float(coords.max() - (L - r))) if coords.size
              else 0.0)
    pcoll_sum = int(out.final.pcoll.sum())
    drift, drift_max = energy_drifts(velocities)
    bound = energy_bound(build, pcoll_sum // 2, energy_ulps)
    return Invariants(
        finite=finite,
        in_box=excess <= tolerance,
        pcoll_even=pcoll_sum % 2 == 0,
        energy=drift_max <= bound,
        energy_drift=drift,
        energy_drift_max=drift_max,
        energy_bound=bound,
        pair_collisions=pcoll_sum // 2,
        box_excess=excess / L,
        states=len(states),
    )
