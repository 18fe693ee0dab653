/*
 * sim_loops.c: the seed's two loop shapes, once, for the variants that choose them (p1/p1d,
 * p2/p2d, relative). The schedule is the variant's choice: the row loop takes it through
 * `schedule(runtime)`, so the static and dynamic strategies run the very same loop; the
 * row-by-row loop applies it to each row's j range.
 */
#include "sim.h"

/* j per tile of p2d's dynamic schedule. Every tile is one grab from the team's shared counter,
 * and between cores that costs far more than testing a few hundred pairs: with 256-j tiles p2d
 * took 3.19 s on the benchmark with 2 threads, with 1024 2.61 s, with 4096 2.43 s (p1d: 2.38 s).
 * Rows longer than a few tiles still balance. */
#define SIM_DYNAMIC_TILE 4096

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
     * 2.48 s -> 2.28 s on the benchmark with 2 threads, as fast as p1. Dynamic: tiles of
     * SIM_DYNAMIC_TILE j are dealt out by `omp for schedule(dynamic) nowait`, one at a time. */
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
            const int32_t j_begin = i + 1;
            const int32_t tiles = (w->n - j_begin + SIM_DYNAMIC_TILE - 1) / SIM_DYNAMIC_TILE;
#pragma omp for schedule(dynamic) nowait
            for (int32_t k = 0; k < tiles; k++) {
                const int32_t j0 = j_begin + k * SIM_DYNAMIC_TILE;
                sim_scan_row(w, i, j0, w->n - j0 < SIM_DYNAMIC_TILE ? w->n : j0 + SIM_DYNAMIC_TILE,
                             buf);
            }
        }
    }
}
