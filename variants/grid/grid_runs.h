/*
 * grid_runs.h: which entries each entry of a binned slice is looked at against, so that every
 * pair whose boxes' cell ranges intersect is looked at exactly once per slice (the "lo corner"
 * rule of docs/grid_design.md). Entry a of cell c = (cx, row) is looked at against two runs of
 * consecutive entries: the rest of its cell, and the next cell when it reaches the next column;
 * then, when it reaches the next row, the cells (cx-1 .. cx+1) of the row above (cx+1 only when
 * it reaches the next column; of cx-1 only the entries reaching its next column, which come
 * last in their cell). A pair of a run that cannot intersect (a cx-1 box that does not reach
 * column cx) is never near, and no pair is in a run of both of its entries. Wide boxes are
 * looked at against the corner cells their range can reach, and against each other. Every
 * run goes through run_prefilter (grid_prefilter.h). Each function returns the pairs looked at.
 */
#ifndef GRID_RUNS_H
#define GRID_RUNS_H

#include "grid_binning.h"
#include "grid_prefilter.h"

/* Entry a of z against the runs [lo1, hi1) and [lo2, hi2). */
static inline int32_t entry_runs(const grid_ctx *cx, const grid_set *z, int32_t a, int32_t lo1,
                                 int32_t hi1, int32_t lo2, int32_t hi2)
{
    const grid_probe p = {z->px[a], z->py[a], z->ux[a], z->uy[a], z->id[a]};
    return run_prefilter(cx, z, lo1, hi1, lo2, hi2, &p);
}

/* Dense grids: the runs' bounds are read from the per-half-cell starts th->pos. */
static uint64_t runs_dense(const grid_ctx *cx, const grid_thread *th, const grid_set *z,
                           const grid_bins *b)
{
    const int32_t w1 = (int32_t)b->spanx;
    const int32_t *restrict pos = th->pos;
    const int32_t *restrict scell = th->scell;
    const uint8_t *restrict sext = th->sext;
    uint64_t tests = 0;
    for (int32_t a = 0; a < b->nbase; a++) {
        const int32_t c = scell[a];
        const unsigned ex = sext[a], xr = ex & GRID_EXT_X;
        /* The rest of cell c (and cell c + 1); the up-left cell's entries that reach its next
         * column, the up cell (and the up-right one). */
        const int up = (ex & GRID_EXT_Y) != 0;
        tests += (uint64_t)entry_runs(cx, z, a, a + 1, pos[2 * (c + 1 + xr)],
                                      up ? pos[2 * (c + w1 - 1) + 1] : 0,
                                      up ? pos[2 * (c + w1 + 1 + xr)] : 0);
    }
    return tests;
}

/* Sparse grids: the same runs, found in the sorted list of cell keys th->skey: the start of the
 * cell's run, the end of its right neighbour, and a pointer into the row above that only moves
 * on. */
static uint64_t runs_sparse(const grid_ctx *cx, const grid_thread *th, const grid_set *z,
                            const grid_bins *b)
{
    const uint64_t *restrict skey = th->skey;
    const uint8_t *restrict sext = th->sext;
    const uint64_t spanx = b->spanx, base_end = b->base_end;
    const int32_t ne = b->ne;
    uint64_t tests = 0;
    int32_t beg = 0, up = 0;
    while (beg < ne && skey[beg] < base_end) {
        const uint64_t key = skey[beg];
        int32_t end = beg;
        while (end < ne && skey[end] == key)
            end++;
        int32_t right_end = end;
        while (right_end < ne && skey[right_end] == key + 1)
            right_end++;
        while (up < ne && skey[up] < key + spanx - 1)
            up++;
        int32_t q = up;
        while (q < ne && skey[q] <= key + spanx)
            q++;
        const int32_t up_end = q;
        while (q < ne && skey[q] == key + spanx + 1)
            q++;
        const int32_t up_end_x = q;
        for (int32_t a = beg; a < end; a++) {
            const unsigned ex = sext[a];
            tests += (uint64_t)entry_runs(
                cx, z, a, a + 1, ex & GRID_EXT_X ? right_end : end, up,
                ex & GRID_EXT_Y ? (ex & GRID_EXT_X ? up_end_x : up_end) : up);
        }
        beg = end;
    }
    return tests;
}

/* Wide boxes against the entries whose base cell is in this band: those with a corner cell in
 * the wide box's range or one column / row before it. */
static uint64_t runs_wide(const grid_ctx *cx, const grid_thread *th, const grid_set *z,
                          const int32_t *wide, const grid_bins *b)
{
    const grid_plan *g = cx->g;
    const float kf = (float)cx->k;
    uint64_t tests = 0;
    for (int32_t m = 0; m < b->nw; m++) {
        const int32_t p = wide[m];
        float bx, by;
        grid_probe pa = {.id = p};
        particle_f32(&cx->s->part[p], g, &bx, &by, &pa.wx, &pa.wy);
        pa.x = slice_start(bx, pa.wx, kf), pa.y = slice_start(by, pa.wy, kf);
        int32_t cxa, cxb, cya, cyb;
        axis_cells(pa.x, pa.wx, g->rpad, g->inv_h, g->topx, &cxa, &cxb);
        axis_cells(pa.y, pa.wy, g->rpad, g->inv_h, g->topy, &cya, &cyb);
        const int32_t ra = cya - 1 > b->row0 ? cya - 1 : b->row0;
        const int32_t rb = cyb < b->row1 - 1 ? cyb : b->row1 - 1;
        for (int32_t row = ra; row <= rb; row++) {
            /* Cells (cxa - 1 .. cxb, row): numbers base + cxa .. base + cxb + 1. */
            const uint64_t base = (uint64_t)(row - b->row0) * b->spanx;
            int32_t lo, hi;
            if (b->dense) {
                lo = th->pos[2 * (base + (uint64_t)cxa)];
                hi = th->pos[2 * (base + (uint64_t)cxb + 2)];
            } else {
                lo = lower_bound(th->skey, b->ne, base + (uint64_t)cxa);
                hi = lower_bound(th->skey, b->ne, base + (uint64_t)cxb + 2);
            }
            tests += (uint64_t)run_prefilter(cx, z, lo, hi, 0, 0, &pa);
        }
    }
    return tests;
}

/* Wide boxes against each other, in double (they are few). */
static uint64_t wide_pairs(const grid_ctx *cx, const int32_t *wide, int32_t nw)
{
    uint64_t tests = 0;
    for (int32_t m = 0; m < nw; m++)
        for (int32_t q = m + 1; q < nw; q++) {
            tests++;
            if (near_pair(cx->s->part, cx->s->tk, cx->g->reach2, wide[m], wide[q], cx->k))
                pair_passed(cx, wide[m], wide[q]);
        }
    return tests;
}

#endif /* GRID_RUNS_H */
