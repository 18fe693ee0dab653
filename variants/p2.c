/*
 * p2: the outer i loop sequential, `omp for` over the inner j loop, static schedule (the seed's
 * second strategy). Each thread tests its static block of every row's j range, with no barrier
 * after a row (see sim_for_row_tiles for why), and the shared kernel vectorises over the block.
 */
#include "core/sim.h"

static void find_pairs(const sim_world *w, sim_pair_sink *sink)
{
    sim_for_row_tiles(w, sink, omp_sched_static);
}

const sim_variant sim_variant_def = {
    .name = "p2", .exact = true, .parallel = true, .find_pairs = find_pairs,
};
