/*
 * grid_runs.c: which entries each entry of a binned slice is looked at against, so that every
 * pair whose boxes' cell ranges intersect is looked at exactly once per slice (the "lo corner"
 * rule of docs/grid_design.md). Entry a of cell c = (cx, row), reaching ex columns right and ey
 * rows up of its corner cell (each at most sub, grid_plan), is looked at against runs of
 * consecutive entries: the rest of its cell and the cells up to cx + ex of its row; then, for
 * each row u = 1 .. ey above, the cells cx - sub .. cx + ex of that row (of cx - sub only the
 * entries reaching sub columns, which come last in their cell). A pair of a run that cannot
 * intersect (a box of a column left of cx that does not reach column cx) is never near, and no
 * pair is in a run of both of its entries. Wide boxes are looked at against the corner cells
 * their range can reach, and against each other. Every run goes through run_prefilter
 * (grid.h). Each function returns the pairs looked at.
 */
#include "grid.h"

/* Entry a of z against the runs [lo1, hi1) and [lo2, hi2). */
static inline int32_t entry_runs(const grid_ctx *cx, const grid_set *z, int32_t a, int32_t lo1,
                                 int32_t hi1, int32_t lo2, int32_t hi2)
{
    const grid_probe p = {z->px[a], z->py[a], z->ux[a], z->uy[a], z->id[a]};
    return run_prefilter(cx, z, lo1, hi1, lo2, hi2, &p);
}

/* Dense grids: the shape of a binned slice's key space, by value. Row u's run of an entry of
 * cell c reaching ex columns goes from cell c + u w1 - sub's entries reaching sub columns to the
 * end of cell c + u w1 + ex (cell c's entries reaching e columns begin at
 * pos[(c << kshift) + e]). */
typedef struct grid_keys {
    const int32_t *pos;
    int32_t w1, sub, kshift;
} grid_keys;

static inline int32_t up_lo(grid_keys k, int32_t c, int32_t u)
{
    return k.pos[((c + u * k.w1 - k.sub) << k.kshift) + k.sub];
}

static inline int32_t up_hi(grid_keys k, int32_t c, int32_t u, int32_t ex)
{
    return k.pos[(c + u * k.w1 + ex + 1) << k.kshift];
}

/* Rows 2 .. ey above entry a (sub > 1 only): out of grid_runs_dense's loop, which keeps the
 * speed of whole-box cells only with one call of the prefilter in it. */
__attribute__((noinline)) static uint64_t upper_runs_dense(const grid_ctx *cx, const grid_set *z,
                                                           grid_keys k, int32_t a, int32_t c,
                                                           int32_t ex, int32_t ey)
{
    return (uint64_t)entry_runs(cx, z, a, up_lo(k, c, 2), up_hi(k, c, 2, ex),
                                ey > 2 ? up_lo(k, c, 3) : 0, ey > 2 ? up_hi(k, c, 3, ex) : 0);
}

/* Dense grids: the runs' bounds are read from the per-key starts th->pos. Inlined into
 * grid_runs_dense twice, for whole-box cells (sub 1, two keys a cell) and for subdivided ones,
 * so that the first has its constants in its instructions: with sub and kshift in registers,
 * the loop took 15 instructions more a probe (cachegrind), and scenes with cells a box wide
 * took up to 10% longer. */
static inline __attribute__((always_inline)) uint64_t
runs_dense_with(const grid_ctx *cx, const grid_thread *th, const grid_set *z, const grid_bins *b,
                int32_t a0, int32_t a1, int32_t sub, int32_t kshift)
{
    const grid_keys k = {th->pos, (int32_t)b->spanx, sub, kshift};
    const int32_t *restrict scell = th->scell;
    const uint8_t *restrict sext = th->sext;
    uint64_t tests = 0;
    for (int32_t a = a0; a < a1; a++) {
        const int32_t c = scell[a];
        const int32_t ex = sext[a] & GRID_EXT_X_MASK, ey = sext[a] >> GRID_EXT_Y_SHIFT;
        /* The rest of cell c and the cells up to c + ex; the first row above. */
        tests += (uint64_t)entry_runs(cx, z, a, a + 1, k.pos[(c + 1 + ex) << k.kshift],
                                      ey ? up_lo(k, c, 1) : 0, ey ? up_hi(k, c, 1, ex) : 0);
        if (sub > 1 && ey > 1)
            tests += upper_runs_dense(cx, z, k, a, c, ex, ey);
    }
    return tests;
}

uint64_t grid_runs_dense(const grid_ctx *cx, const grid_thread *th, const grid_set *z,
                         const grid_bins *b, int32_t a0, int32_t a1)
{
    /* Every subdivision has the shift of GRID_SUB_MAX's, a constant here. */
    return b->sub == 1 ? runs_dense_with(cx, th, z, b, a0, a1, 1, keys_shift(1))
                       : runs_dense_with(cx, th, z, b, a0, a1, b->sub, keys_shift(GRID_SUB_MAX));
}

/* The first of the n sorted keys from `at` on that is >= v (a pointer that only moves on). */
static inline int32_t skip_below(const uint64_t *key, int32_t at, int32_t n, uint64_t v)
{
    while (at < n && key[at] < v)
        at++;
    return at;
}

/* Sparse grids: the same runs, found in the sorted list of cell keys th->skey: the ends of the
 * cell's own row's cells, and for each row above where its run starts and ends, with pointers
 * that only move on. */
uint64_t grid_runs_sparse(const grid_ctx *cx, const grid_thread *th, const grid_set *z,
                          const grid_bins *b)
{
    const uint64_t *restrict skey = th->skey;
    const uint8_t *restrict sext = th->sext;
    const uint64_t spanx = b->spanx, base_end = b->base_end;
    const int32_t ne = b->ne, sub = b->sub;
    uint64_t tests = 0;
    int32_t beg = 0;
    int32_t row_lo[GRID_SUB_MAX + 1] = {0};
    while (beg < ne && skey[beg] < base_end) {
        const uint64_t key = skey[beg];
        /* end[e]: the end of cell key + e's entries, in this row and (row_hi[u][e]) row u. */
        int32_t end[GRID_SUB_MAX + 1], row_hi[GRID_SUB_MAX + 1][GRID_SUB_MAX + 1];
        end[0] = skip_below(skey, beg, ne, key + 1);
        for (int e = 1; e <= sub && e <= GRID_SUB_MAX; e++)
            end[e] = skip_below(skey, end[e - 1], ne, key + (uint64_t)e + 1);
        for (int u = 1; u <= sub && u <= GRID_SUB_MAX; u++) {
            const uint64_t row = key + (uint64_t)u * spanx;
            row_lo[u] = skip_below(skey, row_lo[u], ne, row - (uint64_t)sub);
            int32_t q = row_lo[u];
            for (int e = 0; e <= sub && e <= GRID_SUB_MAX; e++)
                row_hi[u][e] = q = skip_below(skey, q, ne, row + (uint64_t)e + 1);
        }
        for (int32_t a = beg; a < end[0]; a++) {
            const int ex = sext[a] & GRID_EXT_X_MASK, ey = sext[a] >> GRID_EXT_Y_SHIFT;
            tests += (uint64_t)entry_runs(cx, z, a, a + 1, end[ex], ey ? row_lo[1] : 0,
                                          ey ? row_hi[1][ex] : 0);
            for (int u = 2; u <= ey && u <= GRID_SUB_MAX; u++)
                tests += (uint64_t)entry_runs(cx, z, a, row_lo[u], row_hi[u][ex], 0, 0);
        }
        beg = end[0];
    }
    return tests;
}

/* Wide boxes against the entries whose base cell is in this band: those with a corner cell in
 * the wide box's range or up to sub columns / rows before it. */
uint64_t grid_runs_wide(const grid_ctx *cx, const grid_thread *th, const grid_set *z,
                        const int32_t *wide, const grid_bins *b)
{
    const grid_plan *g = cx->g;
    const float kf = (float)cx->k;
    uint64_t tests = 0;
    for (int32_t m = 0; m < b->nw; m++) {
        const int32_t p = wide[m];
        float bx, by;
        grid_probe pa = {.id = p};
        const grid_particle q = grid_part(cx->w, p);
        particle_f32(&q, g, &bx, &by, &pa.wx, &pa.wy);
        pa.x = slice_start(bx, pa.wx, kf), pa.y = slice_start(by, pa.wy, kf);
        int32_t cxa, cxb, cya, cyb;
        axis_cells(pa.x, pa.wx, g->rpad, g->inv_h, g->topx, &cxa, &cxb);
        axis_cells(pa.y, pa.wy, g->rpad, g->inv_h, g->topy, &cya, &cyb);
        const int32_t ra = cya - b->sub > b->row0 ? cya - b->sub : b->row0;
        const int32_t rb = cyb < b->row1 - 1 ? cyb : b->row1 - 1;
        for (int32_t row = ra; row <= rb; row++) {
            /* Cells (cxa - sub .. cxb, row): numbers base + cxa .. base + cxb + sub. */
            const uint64_t base = (uint64_t)(row - b->row0) * b->spanx;
            const uint64_t first = base + (uint64_t)cxa;
            const uint64_t after = base + (uint64_t)cxb + (uint64_t)b->sub + 1;
            int32_t lo, hi;
            if (b->dense) {
                lo = th->pos[first << b->kshift];
                hi = th->pos[after << b->kshift];
            } else {
                lo = grid_lower_bound(th->skey, b->ne, first);
                hi = grid_lower_bound(th->skey, b->ne, after);
            }
            tests += (uint64_t)run_prefilter(cx, z, lo, hi, 0, 0, &pa);
        }
    }
    return tests;
}

/* Wide boxes against each other, in double (they are few). */
uint64_t grid_wide_pairs(const grid_ctx *cx, const int32_t *wide, int32_t nw, int first,
                         int stride)
{
    uint64_t tests = 0;
    for (int32_t m = first; m < nw; m += stride)
        for (int32_t q = m + 1; q < nw; q++) {
            tests++;
            if (near_pair(cx->w, cx->s->tk, cx->g->reach2, wide[m], wide[q], cx->k))
                grid_pair_passed(cx, wide[m], wide[q]);
        }
    return tests;
}
