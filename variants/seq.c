/*
 * seq: every pair i < j, one thread. The baseline every other variant is checked against.
 */
#include "core/sim.h"

static void find_pairs(const sim_world *w, sim_pair_sink *sink)
{
    for (int32_t i = 0; i < w->n; i++)
        sim_scan_full_row(w, i, sim_sink_buf(sink, 0));
}

const sim_variant sim_variant_def = {
    .name = "seq", .exact = true, .parallel = false, .find_pairs = find_pairs,
};
