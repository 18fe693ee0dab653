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
    if (g.bands == 1) {
        sim_cand_buf *buf = sim_sink_buf(sink, 0);
        const double t0 = sim_busy_start();
        grid_run_alone(w, s, &g, buf);
        sim_busy_stop(buf, t0);
    } else {
#pragma omp parallel num_threads(g.bands)
        grid_run_team(w, s, &g, omp_get_thread_num(), omp_get_num_threads(),
                      sim_sink_buf(sink, omp_get_thread_num()));
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
