/*
 * p2d: p2 with `schedule(dynamic)` (the seed's fifth strategy): each row's j range goes out in
 * tiles, one at a time, to whichever thread is free.
 */
#include "core/sim.h"

static void find_pairs(const sim_world *w, sim_pair_sink *sink)
{
    sim_for_row_tiles(w, sink, omp_sched_dynamic);
}

const sim_variant sim_variant_def = {
    .name = "p2d", .exact = true, .parallel = true, .find_pairs = find_pairs,
};
