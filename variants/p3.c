/*
 * p3, the seed's third strategy as written: "both loops parallel, nested, two active levels":
 * `#pragma omp parallel for` over i and, inside it, `#pragma omp parallel for` over j (static).
 * Shows oversubscription and region cost: the outer team and every inner team each ask for the
 * run's thread count T, so T*T threads compete for T cores, and every row creates a team.
 * Each (outer, inner) thread pair writes its own buffer: omp_get_thread_num() alone repeats
 * across inner teams. The j loop runs over tiles of SIM_TILE j (as in p2), and the inner `omp
 * for` is `nowait` inside its region so that each inner thread's timer stops when it is done.
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
#pragma omp parallel num_threads(team)
        {
            sim_cand_buf *buf = sim_sink_buf(sink, outer * team + omp_get_thread_num());
            const double t0 = sim_busy_start();
            int32_t last = -2;
#pragma omp for schedule(static) nowait
            for (int32_t k = 0; k < tiles; k++) {
                buf->chunks += k != last + 1;
                last = k;
                sim_scan_tile(w, i, k, buf);
            }
            sim_busy_stop(buf, t0);
        }
    }
}

/* the outer region per step, and an inner region per row forked by the outer team's threads */
static const sim_sync sync = {.regions = {.per_step = 1}, .nested_regions = {.per_row = 1}};

const sim_variant sim_variant_def = {
    .name = "p3",
    .summary = "the seed's: both loops parallel, nested, two active levels "
               "(T x T threads, a team per row)",
    .exact = true,
    .parallel = true,
    .all_pairs = true,
    .repairs = NULL,
    .sync = &sync,
    .buffer_count = buffer_count,
    .find_pairs = find_pairs,
};
