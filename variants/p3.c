/*
 * p3: both loops parallel, nested, two active levels (the seed's third strategy). As in the
 * seed, the outer team and every inner team each ask for the run's thread count T, so up to
 * T*T threads compete for T cores: the oversubscription is what this strategy is measured for.
 * Each (outer, inner) thread pair writes its own buffer: omp_get_thread_num() alone repeats
 * across inner teams.
 */
#include <omp.h>

#include "core/sim.h"

static int buffer_count(int threads)
{
    return threads * threads;
}

static void find_pairs(const sim_world *w, sim_pair_sink *sink)
{
    const int team = sink->threads;
    omp_set_max_active_levels(2);
#pragma omp parallel for schedule(static) num_threads(team)
    for (int32_t i = 0; i < w->n; i++) {
        const int32_t tiles = sim_row_tiles(w, i);
        const int outer = omp_get_thread_num();
#pragma omp parallel for schedule(static) num_threads(team)
        for (int32_t k = 0; k < tiles; k++)
            sim_scan_tile(w, i, k, sim_sink_buf(sink, outer * team + omp_get_thread_num()));
    }
}

const sim_variant sim_variant_def = {
    .name = "p3",
    .exact = true,
    .parallel = true,
    .buffer_count = buffer_count,
    .find_pairs = find_pairs,
};
