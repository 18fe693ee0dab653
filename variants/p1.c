/*
 * p1, the seed's first strategy as written: "`#pragma omp parallel for` over the outer i loop"
 * (default static schedule, no chunk). Shows load imbalance over the triangle of pairs: row i
 * holds n-1-i pairs and each thread gets one contiguous block of rows, so on two threads the
 * first gets 3/4 of the pairs and the speedup is capped at 4/3. Its repair: p1_cyclic.
 */
#include "core/sim.h"

static void find_pairs(const sim_world *w, sim_pair_sink *sink)
{
    sim_rows_static(w, sink, sim_scan_full_row); /* omp for schedule(static) */
}

/* one region per step (its static schedule deals rows without a runtime call) */
static const sim_sync sync = {.regions = {.per_step = 1}};

const sim_variant sim_variant_def = {
    .name = "p1",
    .summary =
        "the seed's: omp parallel for over the outer i loop, default static schedule (one "
        "contiguous block of rows per thread)",
    .exact = true,
    .parallel = true,
    .all_pairs = true,
    .repairs = NULL,
    .sync = &sync,
    .find_pairs = find_pairs,
};
