"""Uncertainty of the numbers the harness compares, from hyperfine's per-run times, with
scipy.stats: bootstrap intervals of medians and their ratios and differences (intervals),
intervals over rounds and sessions (levels), the sign test of two sides measured together
(paired), and the verdicts with the change of two measured apart (verdicts). The bootstrap is
seeded from the data, so that the same times always give the same interval: results.csv and the
report do not change when nothing was re-measured.

Why the percentile bootstrap and not BCa: with the 3-5 runs most configs take, BCa's jackknife
acceleration is degenerate (and scipy warns); the percentile interval of a median of n runs
is the span of the middle order statistics, which is what a reader expects.

What "95%" means with few runs (measured in tests/test_stats.py): the bootstrap cannot reach
beyond the sample, so with 3 runs the interval of a median is [min, max], which holds the true
median with probability 1 - 2/2^3 = 75% whatever the distribution; from 5 runs on it covers
about 93-95%. A ratio of two 3-run medians gets [min/max', max/min'], which misses 1 for two
identical distributions with probability 2/20 = 10% (the chance that one sample lies wholly
above the other). That is why a verdict of compare never rests on such an interval alone: it
tests against a threshold, and widens the interval of runs measured apart by the drift.

The names other modules use are re-exported here: callers use `stats.NAME`.
"""

from harness.stats.intervals import (CONFIDENCE, DEFAULT_ESTIMATOR, ESTIMATORS, Interval,
                                     difference_ci, efficiency, estimate, estimate_ci, karp_flatt,
                                     median_ci, power_fit, ratio_ci, serial_fraction, speedup_ci)
from harness.stats.levels import (DEFAULT_SESSION_SPREAD, INTERVAL_MIN_ROUNDS, MIN_ROUNDS,
                                  NOISE_MARGIN, Coverage, RoundEstimate, SessionSpread,
                                  cell_estimate, coverage, from_round_values, paired_ratio,
                                  round_half_width, session_noise, session_spread, spread_at,
                                  spreads_of, supersedes, t95, time_interval)
from harness.stats.paired import (DISTURBED_LIMIT, NOISE_LIMIT, SHIFT_MIN_ROUNDS, MeasuredInRounds,
                                  NoiseProfile, PairedRounds, interference_slope, noise_profile,
                                  paired_change, paired_series, paired_sides, round_medians,
                                  rounds_to_drop, smallest_detectable, without_interference)
from harness.stats.verdicts import (FASTER, FIRST_LOOK_ROUNDS, INCONCLUSIVE, LAST_LOOK,
                                    NO_CHANGE_KNOWN, NOISE_DRIFT_SLOPE, PRESSURE_SLOPE, SLOWER,
                                    UNCHANGED, VERDICTS, Change, contention_spread, decide,
                                    discoveries, drift_change, further_rounds, log_ratio_drift,
                                    log_spread, look_index, look_rounds, look_weight, noise_drift,
                                    paired_look)
