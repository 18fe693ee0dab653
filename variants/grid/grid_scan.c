/*
 * grid_scan.c: a work item of the finder: a block of consecutive slices of one band. Each
 * slice is binned (grid_binning.c) from the previous slice's entries, which are already in
 * nearly the right order, then every pair of the band is looked at once (grid_runs.c); the
 * step's last slice also leaves the cell order the next step starts from.
 */
#include <string.h>

#include "grid.h"

/* Slice cx->k, band `band`: bin the source into th->set[out] / th->wide[out] (returning their
 * sizes) and look at every pair of the band once. */
static void run_slice(const grid_ctx *cx, grid_thread *th, int band, const grid_src *src,
                      int out, int32_t *ne_out, int32_t *nw_out)
{
    const grid_scratch *s = cx->s;
    grid_set *dst = &th->set[out];
    int32_t *wide = th->wide[out];
    grid_bins b;
    grid_bin_slice(src, s->part, cx->g, (float)cx->k, band, th, dst, wide, &b);
    *ne_out = b.ne;
    *nw_out = b.nw;
    if (cx->ord_next) {
        /* The bands' base entries, in band order, then the wide particles: every particle
         * once, in this slice's cell order. */
        memcpy(cx->ord_next + b.below, dst->id, (size_t)b.nbase * sizeof(int32_t));
        if (band == 0)
            memcpy(cx->ord_next + (s->n - b.nw), wide, (size_t)b.nw * sizeof(int32_t));
    }
    uint64_t tests = b.dense ? grid_runs_dense(cx, th, dst, &b) : grid_runs_sparse(cx, th, dst, &b);
    tests += grid_runs_wide(cx, th, dst, wide, &b);
    /* Wide boxes against each other, once per slice. */
    if (band == 0)
        tests += grid_wide_pairs(cx, wide, b.nw);
    grid_queue_flush(cx);
    cx->buf->pair_tests += tests;
}

/* Each slice after the first reads the previous one's entries, already in nearly the right
 * order (only possible when the band is the whole grid). */
void grid_run_item(const sim_world *w, const grid_scratch *s, grid_thread *th,
                   const grid_plan *g, int k0, int k1, int band, sim_cand_buf *buf)
{
    grid_src src = {.bx = s->bx, .by = s->by, .ux = s->ux, .uy = s->uy, .id = s->ord, .m = s->n,
                    .wide = NULL, .nwide = 0};
    int out = 0;
    grid_queue queue = {.at = 0, .len = 0, .on = s->n > GRID_SMALL_N};
    for (int k = k0; k < k1; k++) {
        const grid_ctx cx = {.w = w, .s = s, .g = g, .k = k, .buf = buf,
                             .ord_next = k == g->K - 1 ? s->ord_next : NULL, .queue = &queue};
        int32_t ne, nw;
        run_slice(&cx, th, band, &src, out, &ne, &nw);
        const grid_set *z = &th->set[out];
        src = (grid_src){.bx = z->bx, .by = z->by, .ux = z->ux, .uy = z->uy, .id = z->id, .m = ne,
                         .wide = th->wide[out], .nwide = nw};
        out ^= 1;
    }
}
