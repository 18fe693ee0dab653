/*
 * sim_loops.c: the seed's two loop shapes, once, for the variants that choose them (p1/p1d,
 * p2/p2d, relative). The schedule is the variant's choice: the row loop takes it through
 * `schedule(runtime)`, so the static and dynamic strategies run the very same loop; the
 * row-by-row loop applies it to each row's j range.
 */
#include "sim.h"

void sim_scan_full_row(const sim_world *w, int32_t i, sim_cand_buf *buf)
{
    sim_scan_row(w, i, i + 1, w->n, buf);
}

void sim_for_rows(const sim_world *w, sim_pair_sink *sink, omp_sched_t schedule, int chunk,
                  sim_row_scan_fn *scan)
{
    omp_set_schedule(schedule, chunk);
#pragma omp parallel
    {
        sim_cand_buf *buf = sim_sink_buf(sink, omp_get_thread_num());
#pragma omp for schedule(runtime)
        for (int32_t i = 0; i < w->n; i++)
            scan(w, i, buf);
    }
}

void sim_for_row_tiles(const sim_world *w, sim_pair_sink *sink, omp_sched_t schedule)
{
    /* One region for all rows, and no barrier after a row. The seed forked a team per row, and
     * a plain `omp for` would still end every row in a barrier: 10,000 barriers a step on the
     * benchmark, which cost p2 a fifth of its time on two threads (1.66x against seq, measured
     * by make bench). Rows are independent (every thread writes its own buffer and nobody
     * reads them until the region ends), so no thread needs to wait for a row to finish.
     *
     * Static: thread t of T tests the t-th of T contiguous, near-equal blocks of the row's j
     * range, which is what OpenMP's static schedule without a chunk does; it is computed here,
     * not by `omp for` over tiles, because tiles of SIM_TILE leave the first thread one tile
     * more in half of the rows (the blocks of a row differ by a tile; without barriers that adds
     * up to 5% of the work) and the runtime call per row costs more than the arithmetic:
     * 2.48 s -> 2.28 s on the benchmark with 2 threads, as fast as p1. Dynamic: the tiles are
     * dealt out by `omp for schedule(dynamic) nowait`, one at a time. */
#pragma omp parallel
    {
        const int t = omp_get_thread_num(), team = omp_get_num_threads();
        sim_cand_buf *buf = sim_sink_buf(sink, t);
        for (int32_t i = 0; i < w->n; i++) {
            if (schedule == omp_sched_static) {
                const int64_t len = (int64_t)w->n - 1 - i;
                sim_scan_row(w, i, i + 1 + (int32_t)(len * t / team),
                             i + 1 + (int32_t)(len * (t + 1) / team), buf);
                continue;
            }
            const int32_t tiles = sim_row_tiles(w, i);
#pragma omp for schedule(dynamic) nowait
            for (int32_t k = 0; k < tiles; k++)
                sim_scan_tile(w, i, k, buf);
        }
    }
}
