/*
 * sim_loops.c: the seed's outer-loop shape (rows shared out over one team), once per schedule,
 * for the variants that choose one (p1, p1_cyclic, p1d, p1_runtime, relative). Each helper is
 * named for its schedule and spells the clause out, so what a variant runs is visible, not a
 * runtime setting; the row-by-row (p2) shapes differ enough to live in their variant files.
 *
 * The seed wrote `#pragma omp parallel for`; here it is `omp parallel` around `omp for ...
 * nowait`, the same loop with the same iterations to the same threads, only so that each thread
 * can stop its timer when its rows are done: the region's end is then the loop's barrier.
 */
#include "sim.h"

void sim_scan_full_row(const sim_world *w, int32_t i, sim_cand_buf *buf)
{
    sim_scan_row(w, i, i + 1, w->n, buf);
}

/* One row loop under `omp_for` (a pragma string). Chunks are counted as they are dealt: a
 * thread's chunk starts where its rows stop being consecutive (one block of a plain static
 * schedule) or at each multiple of `every` (schedules with a fixed chunk `every`: the runtime
 * deals chunks starting at multiples of it). `every` = 0: only the first rule, which undercounts
 * only guided chunks (sizes the runtime alone knows) that one thread takes back to back. */
#define SIM_ROW_LOOP(NAME, OMP_FOR, EVERY)                                                      \
    void NAME(const sim_world *w, sim_pair_sink *sink, sim_row_scan_fn *scan)                  \
    {                                                                                           \
        /* 1 for "no fixed chunk", so that the division is always defined */                   \
        const int32_t every = (EVERY) > 0 ? (EVERY) : 1, fixed = (EVERY) > 0;                   \
        _Pragma("omp parallel")                                                                 \
        {                                                                                       \
            sim_cand_buf *buf = sim_sink_buf(sink, omp_get_thread_num());                      \
            int32_t last = -2;                                                                  \
            const double t0 = sim_busy_start();                                                 \
            _Pragma(OMP_FOR)                                                                    \
            for (int32_t i = 0; i < w->n; i++) {                                                \
                buf->chunks += i != last + 1 || (fixed && i % every == 0);                  \
                last = i;                                                                       \
                scan(w, i, buf);                                                                \
            }                                                                                   \
            sim_busy_stop(buf, t0);                                                             \
        }                                                                                       \
    }

/* The chunk rule of the schedule OMP_SCHEDULE (or omp_set_schedule) selected. */
static int32_t runtime_every(void)
{
    omp_sched_t kind;
    int chunk;
    omp_get_schedule(&kind, &chunk);
    switch ((int)kind & ~(int)omp_sched_monotonic) {
    case omp_sched_static:
        return chunk > 0 ? chunk : 0;
    case omp_sched_dynamic:
        return chunk > 0 ? chunk : 1;
    default: /* guided, auto: chunk sizes are the runtime's */
        return 0;
    }
}

SIM_ROW_LOOP(sim_rows_static, "omp for schedule(static) nowait", 0)
SIM_ROW_LOOP(sim_rows_cyclic, "omp for schedule(static, 1) nowait", 1)
SIM_ROW_LOOP(sim_rows_dynamic, "omp for schedule(dynamic) nowait", 1)
SIM_ROW_LOOP(sim_rows_runtime, "omp for schedule(runtime) nowait", runtime_every())
