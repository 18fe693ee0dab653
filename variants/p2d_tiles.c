/*
 * p2d_tiles: p2d repaired: one region for all rows, and each row's j range dealt out in tiles of
 * P2D_TILE j by `schedule(dynamic) nowait` (no barrier after a row). Every tile is one grab from
 * the team's shared counter, which between cores costs far more than a few hundred pair tests:
 * with 256-j tiles this loop took 3.19 s on the benchmark with 2 threads, with 1024 2.61 s, with
 * 4096 2.43 s (p1d: 2.38 s). Rows longer than a few tiles still balance.
 */
#include "core/sim.h"

#define P2D_TILE 4096 /* j per dynamic chunk */
#define P2D_TEXT_(x) #x
#define P2D_TEXT(x) P2D_TEXT_(x) /* P2D_TILE as text, for the summary */

static void find_pairs(const sim_world *w, sim_pair_sink *sink)
{
#pragma omp parallel
    {
        sim_cand_buf *buf = sim_sink_buf(sink, omp_get_thread_num());
        const double t0 = sim_busy_start();
        for (int32_t i = 0; i < w->n; i++) {
            const int32_t tiles = (w->n - (i + 1) + P2D_TILE - 1) / P2D_TILE;
#pragma omp for schedule(dynamic) nowait
            for (int32_t k = 0; k < tiles; k++) {
                const int32_t j0 = i + 1 + k * P2D_TILE;
                buf->chunks++;
                sim_scan_row(w, i, j0, w->n - j0 < P2D_TILE ? w->n : j0 + P2D_TILE, buf);
            }
        }
        sim_busy_stop(buf, t0);
    }
}

/* one region per step, one grab per tile of a row */
static const sim_sync sync = {.regions = {.per_step = 1}, .grabs = {.per_tile = 1}, .tile = P2D_TILE};

const sim_variant sim_variant_def = {
    .name = "p2d_tiles",
    .summary = "p2d repaired: one region, schedule(dynamic) over tiles of " P2D_TEXT(P2D_TILE)
               " j, no barrier between rows",
    .exact = true,
    .parallel = true,
    .all_pairs = true,
    .repairs = "p2d",
    .sync = &sync,
    .find_pairs = find_pairs,
};
