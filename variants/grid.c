/*
 * grid: a space-time broad phase. Only pairs that can meet within the step are tested, with
 * the shared kernel (sim_pair_time), so the candidates, and the output, are those of seq, for
 * every input and thread count. docs/grid_design.md explains the design (time slices, float
 * binning, the lo-corner rule, exactly-once, work items). This file is the finder: the plan of
 * the step, then its work items shared out to the threads; the pieces that do the work are the
 * files of variants/grid/ (grid/grid.h lists them).
 */
#include <omp.h>

#include "grid/grid.h"

static void find_pairs(const sim_world *w, sim_pair_sink *sink)
{
    grid_scratch *s = sink->scratch;
    if (w->n < 2)
        return;
    grid_plan g;
    grid_plan_step(w, s, &g, sink->threads);
    const int threads = sink->threads;
    const int items = g.bands > 1 ? g.K * g.bands : g.blocks;
#pragma omp parallel num_threads(threads) if (threads > 1)
    {
        const int tid = omp_get_thread_num();
        sim_cand_buf *buf = sim_sink_buf(sink, tid);
        const double t0 = sim_busy_start();
#pragma omp for schedule(dynamic, 1) nowait
        for (int i = 0; i < items; i++) {
            buf->chunks++;
            if (g.bands > 1)
                grid_run_item(w, s, &s->th[tid], &g, i / g.bands, i / g.bands + 1, i % g.bands,
                              buf);
            else
                grid_run_item(w, s, &s->th[tid], &g, (int)((int64_t)i * g.K / items),
                              (int)((int64_t)(i + 1) * g.K / items), 0, buf);
        }
        sim_busy_stop(buf, t0);
    }
    int32_t *t = s->ord;
    s->ord = s->ord_next;
    s->ord_next = t;
}

const sim_variant sim_variant_def = {
    .name = "grid",
    .summary = "space-time grid: only pairs that can meet within the step are tested; parallel",
    .exact = true,
    .parallel = true,
    .all_pairs = false,
    .repairs = NULL,
    .scratch_create = grid_scratch_create,
    .scratch_destroy = grid_scratch_destroy,
    .find_pairs = find_pairs,
};
