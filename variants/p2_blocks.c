/*
 * p2_blocks: p2 repaired: one parallel region for all rows and no barrier between them. Thread
 * t of T tests the t-th of T contiguous, near-equal blocks of each row's j range (what the
 * static schedule without a chunk deals), computed here rather than by `omp for`: rows are
 * independent (every thread writes its own buffer, read only after the region), so nobody needs
 * to wait for a row to finish, and the arithmetic costs less than a runtime call per row.
 */
#include "core/sim.h"

static void find_pairs(const sim_world *w, sim_pair_sink *sink)
{
#pragma omp parallel
    {
        const int t = omp_get_thread_num(), team = omp_get_num_threads();
        sim_cand_buf *buf = sim_sink_buf(sink, t);
        const double t0 = sim_busy_start();
        for (int32_t i = 0; i < w->n; i++) {
            const int64_t len = (int64_t)w->n - 1 - i;
            const int32_t j0 = i + 1 + (int32_t)(len * t / team);
            const int32_t j1 = i + 1 + (int32_t)(len * (t + 1) / team);
            buf->chunks += j1 > j0;
            sim_scan_row(w, i, j0, j1, buf);
        }
        sim_busy_stop(buf, t0);
    }
}

/* one region per step */
static const sim_sync sync = {.regions = {.per_step = 1}};

const sim_variant sim_variant_def = {
    .name = "p2_blocks",
    .summary =
        "p2 repaired: one region for all rows, each thread a static block of every row, no "
        "barrier between rows",
    .exact = true,
    .parallel = true,
    .all_pairs = true,
    .repairs = "p2",
    .sync = &sync,
    .find_pairs = find_pairs,
};
