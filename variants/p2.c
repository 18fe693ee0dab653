/*
 * p2: the outer i loop sequential, `omp for` over the inner j loop, static schedule (the seed's
 * second strategy). Each row is one worksharing loop (see sim_for_row_tiles for why it has no
 * barrier). The j loop is dealt out in tiles of SIM_TILE pairs rather than single j so the
 * shared kernel still vectorises; which tiles a thread tests is the schedule's decision.
 */
#include "core/sim.h"

static void find_pairs(const sim_world *w, sim_pair_sink *sink)
{
    sim_for_row_tiles(w, sink, omp_sched_static);
}

const sim_variant sim_variant_def = {
    .name = "p2", .exact = true, .parallel = true, .find_pairs = find_pairs,
};
