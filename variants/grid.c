/*
 * grid: a space-time broad phase. Only pairs that can meet within the step are tested, with
 * the shared kernel (sim_pair_time), so the candidates, and the output, are those of seq, for
 * every input and thread count. docs/grid_design.md explains the design (time slices, float
 * binning, the lo-corner rule, exactly-once, work items). This file is the variant's
 * definition; the finder (grid_find_pairs, grid/grid_finder.c) and the pieces that do its work
 * are the files of variants/grid/ (grid/grid.h lists them), which the mpi variant links too.
 */
#include "grid/grid.h"

const sim_variant sim_variant_def = {
    .name = "grid",
    .summary = "space-time grid: only pairs that can meet within the step are tested; parallel",
    .exact = true,
    .parallel = true,
    .all_pairs = false,
    .repairs = NULL,
    .scratch_create = grid_scratch_create,
    .scratch_destroy = grid_scratch_destroy,
    .find_pairs = grid_find_pairs,
};
