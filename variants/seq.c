/*
 * seq: every pair i < j, one thread. The baseline every other variant is checked against.
 */
#include "core/sim.h"

static void find_pairs(const sim_world *w, sim_pair_sink *sink)
{
    sim_cand_buf *buf = sim_sink_buf(sink, 0);
    const double t0 = sim_busy_start();
    for (int32_t i = 0; i < w->n; i++)
        sim_scan_full_row(w, i, buf);
    buf->chunks++;
    sim_busy_stop(buf, t0);
}

/* one thread: no region, no runtime call */
static const sim_sync sync = {0};

const sim_variant sim_variant_def = {
    .name = "seq",
    .summary = "every pair i < j, one thread; the baseline",
    .exact = true,
    .parallel = false,
    .all_pairs = true,
    .repairs = NULL,
    .sync = &sync,
    .find_pairs = find_pairs,
};
