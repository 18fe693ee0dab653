/*
 * p2, the seed's second strategy as written: "the outer i loop sequential, `#pragma omp parallel
 * for` over the inner j loop" (default static schedule). Shows the cost of a parallel region per
 * row: a team fork and a barrier for each of the n rows, every step, and the shrinking rows
 * leave the team less and less to share. Its repair: p2_blocks.
 *
 * The j loop runs over tiles of SIM_TILE j rather than single j, so the kernel vectorises as in
 * every other variant: the static schedule gives each thread one contiguous block of the row
 * either way. `omp parallel` around `omp for nowait` is `omp parallel for` with the barrier at
 * the region's end, so that each thread's timer stops when its block is done.
 */
#include "core/sim.h"

static void find_pairs(const sim_world *w, sim_pair_sink *sink)
{
    for (int32_t i = 0; i < w->n; i++) {
        const int32_t tiles = sim_row_tiles(w, i);
#pragma omp parallel
        {
            sim_cand_buf *buf = sim_sink_buf(sink, omp_get_thread_num());
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

/* a region per row */
static const sim_sync sync = {.regions = {.per_row = 1}};

const sim_variant sim_variant_def = {
    .name = "p2",
    .summary =
        "the seed's: outer loop sequential, omp parallel for over the inner j loop (static; a "
        "team fork and a barrier per row)",
    .exact = true,
    .parallel = true,
    .all_pairs = true,
    .repairs = NULL,
    .sync = &sync,
    .find_pairs = find_pairs,
};
