/*
 * p1_runtime: p1 with `schedule(runtime)`, the schedule study's subject: OMP_SCHEDULE (e.g.
 * "static", "static,1", "dynamic,64", "guided") picks how rows are shared out, so one binary
 * runs them all (configs/schedules.yaml). Without OMP_SCHEDULE libgomp uses dynamic, chunk 1.
 */
#include "core/sim.h"

static void find_pairs(const sim_world *w, sim_pair_sink *sink)
{
    sim_rows_runtime(w, sink, sim_scan_full_row); /* omp for schedule(runtime) */
}

const sim_variant sim_variant_def = {
    .name = "p1_runtime",
    .summary = "p1 with schedule(runtime): OMP_SCHEDULE picks the schedule (the schedule study)",
    .exact = true,
    .parallel = true,
    .all_pairs = true,
    .repairs = NULL,
    .find_pairs = find_pairs,
};
