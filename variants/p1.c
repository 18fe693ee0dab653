/*
 * p1: `omp parallel for` over the outer i loop, static schedule (the seed's first strategy).
 * Row i holds n-1-i pairs. The default static schedule (one contiguous block of rows per
 * thread) gives the first thread 3/4 of the pairs on two threads, capping the speedup at 4/3;
 * a static schedule with chunk 1 deals rows round-robin, which balances the triangle with no
 * runtime cost. It is still static: which thread tests which row is fixed before the loop runs,
 * and that is what p1 is compared with p1d for.
 */
/* Rows dealt one at a time, round-robin. */
#define P1_CHUNK 1

#include "core/sim.h"

static void find_pairs(const sim_world *w, sim_pair_sink *sink)
{
    sim_for_rows(w, sink, omp_sched_static, P1_CHUNK, sim_scan_full_row);
}

const sim_variant sim_variant_def = {
    .name = "p1", .exact = true, .parallel = true, .find_pairs = find_pairs,
};
