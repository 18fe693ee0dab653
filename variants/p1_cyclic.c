/*
 * p1_cyclic: p1 repaired with `schedule(static, 1)`: rows dealt round-robin, so every thread
 * gets long early rows and short late ones alike and the triangle balances, at no runtime cost
 * (which thread tests which row is still fixed before the loop runs).
 */
#include "core/sim.h"

static void find_pairs(const sim_world *w, sim_pair_sink *sink)
{
    sim_rows_cyclic(w, sink, sim_scan_full_row); /* omp for schedule(static, 1) */
}

/* one region per step; schedule(static, 1) deals rows by arithmetic */
static const sim_sync sync = {.regions = {.per_step = 1}};

const sim_variant sim_variant_def = {
    .name = "p1_cyclic",
    .summary = "p1 repaired: schedule(static, 1), rows dealt round-robin",
    .exact = true,
    .parallel = true,
    .all_pairs = true,
    .repairs = "p1",
    .sync = &sync,
    .find_pairs = find_pairs,
};
