/*
 * p1d, the seed's fourth strategy as written: "p1 with `schedule(dynamic)`" (chunk 1). Shows
 * that a dynamic schedule repairs p1's imbalance: threads take rows one at a time from a shared
 * counter, for one counter increment per row (10,000 a step on the benchmark: cheap next to a
 * row's thousands of pair tests).
 */
#include "core/sim.h"

static void find_pairs(const sim_world *w, sim_pair_sink *sink)
{
    sim_rows_dynamic(w, sink, sim_scan_full_row); /* omp for schedule(dynamic) */
}

/* one region per step, one grab per row */
static const sim_sync sync = {.regions = {.per_step = 1}, .grabs = {.per_row = 1}};

const sim_variant sim_variant_def = {
    .name = "p1d",
    .summary = "the seed's: p1 with schedule(dynamic) (one row per grab)",
    .exact = true,
    .parallel = true,
    .all_pairs = true,
    .repairs = NULL,
    .sync = &sync,
    .find_pairs = find_pairs,
};
