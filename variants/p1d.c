/*
 * p1d: p1 with `schedule(dynamic)` (the seed's fourth strategy): threads take rows one at a
 * time, so the long early rows and the short late ones spread evenly, for one shared counter
 * increment per row.
 */
#include "core/sim.h"

static void find_pairs(const sim_world *w, sim_pair_sink *sink)
{
    sim_for_rows(w, sink, omp_sched_dynamic, 0, sim_scan_full_row);
}

const sim_variant sim_variant_def = {
    .name = "p1d", .exact = true, .parallel = true, .find_pairs = find_pairs,
};
