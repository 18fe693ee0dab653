/*
 * p2d, the seed's fifth strategy as written: "p2 with `schedule(dynamic)`" over single j (chunk
 * 1). Shows the overhead of dynamic scheduling on a short loop body: every pair test is one grab
 * from the team's shared counter (n(n-1)/2 grabs a step, the counter's cache line bouncing
 * between cores), on top of p2's fork and barrier per row. The seed measured 94.24 s here
 * against p2's 8.51 s. Its repair: p2d_tiles.
 */
#include "core/sim.h"

static void find_pairs(const sim_world *w, sim_pair_sink *sink)
{
    for (int32_t i = 0; i < w->n; i++) {
#pragma omp parallel
        {
            sim_cand_buf *buf = sim_sink_buf(sink, omp_get_thread_num());
            const double t0 = sim_busy_start();
#pragma omp for schedule(dynamic) nowait
            for (int32_t j = i + 1; j < w->n; j++) {
                buf->chunks++;
                sim_scan_row(w, i, j, j + 1, buf);
            }
            sim_busy_stop(buf, t0);
        }
    }
}

/* a region per row, one grab per pair test */
static const sim_sync sync = {.regions = {.per_row = 1}, .grabs = {.per_pair = 1}};

const sim_variant sim_variant_def = {
    .name = "p2d",
    .summary = "the seed's: p2 with schedule(dynamic) over single j (one grab per pair test)",
    .exact = true,
    .parallel = true,
    .all_pairs = true,
    .repairs = NULL,
    .sync = &sync,
    .find_pairs = find_pairs,
};
