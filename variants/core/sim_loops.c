/*
 * sim_loops.c: the seed's two loop shapes, once, for the variants that choose them (p1/p1d,
 * p2/p2d, relative). The schedule is the variant's choice and reaches the loop through
 * `schedule(runtime)`, so the static and dynamic strategies run the very same loop.
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
    omp_set_schedule(schedule, 0);
    /* One region for all rows, and `nowait` on each row's loop. The seed forked a team per row,
     * and a plain `omp for` would still end every row in a barrier: 10,000 barriers a step on
     * the benchmark, which cost p2 a fifth of its time on two threads (1.66x against seq,
     * measured by make bench). Rows are independent (every thread writes its own buffer and
     * nobody reads them until the region ends), so no thread needs to wait for a row to finish;
     * the schedule still decides which tiles of each row a thread tests. */
#pragma omp parallel
    {
        sim_cand_buf *buf = sim_sink_buf(sink, omp_get_thread_num());
        for (int32_t i = 0; i < w->n; i++) {
            const int32_t tiles = sim_row_tiles(w, i);
#pragma omp for schedule(runtime) nowait
            for (int32_t k = 0; k < tiles; k++)
                sim_scan_tile(w, i, k, buf);
        }
    }
}
