/*
 * grid_binning.c: one slice's entries in cell order. Every item's key (dense grids, slice_keys:
 * its cell and how far right it reaches) or corner cell and flags (sparse grids, item_cells),
 * vectorised, then either a counting sort into per-key starts (bin_dense) or an LSD radix sort
 * of (cell, reach bits, index) words (bin_sparse), writing the entries' floats, ids and reach
 * bits into the thread's output set; wide particles go to a list of their own. The result is a
 * grid_bins, which grid_runs.c reads.
 */
#include <string.h>

#include "grid.h"

/* Every item's corner cell and flags in slice k (as a float). One loop the compiler
 * vectorises. */
static void slice_cells(int32_t m, const float *restrict bx, const float *restrict by,
                        const float *restrict ux, const float *restrict uy, float k,
                        const grid_plan *g, int32_t *restrict cx0, int32_t *restrict cy0,
                        int32_t *restrict flag)
{
    for (int32_t p = 0; p < m; p++)
        box_cells(slice_start(bx[p], ux[p], k), slice_start(by[p], uy[p], k), ux[p], uy[p], g,
                  &cx0[p], &cy0[p], &flag[p]);
}

/* Dense grids: every item's key in slice k (as a float), 2^kshift c + (how many columns it
 * reaches beyond its corner cell) for cell number c (grid_bins), or GRID_KEY_WIDE / _BELOW /
 * _ABOVE, and its flags. One loop the compiler vectorises: the counting sort's two
 * passes then read one key an item. Within a cell the entries reaching further right come
 * later. */
#define GRID_KEY_WIDE (-1)
#define GRID_KEY_BELOW (-2)
#define GRID_KEY_ABOVE (-3)
static inline int32_t item_key(int32_t cx, int32_t cy, int32_t f, int32_t row0, int32_t rowlast,
                               int32_t spanx, int32_t sub, int32_t kshift)
{
    /* In unsigned arithmetic, which wraps where int32 would overflow: for a row far outside
     * the band (a wide grid cut into bands) (cy - row0) * spanx can, and then the key is not
     * h anyway. The same instructions as in int32; clipping the row first cost 7% of the
     * report benchmark's finder. */
    const int32_t h =
        (int32_t)(((uint32_t)(cy - row0) * (uint32_t)spanx + (uint32_t)(cx + sub)) << kshift |
                  (uint32_t)(f & GRID_EXT_X_MASK));
    return f & GRID_WIDE ? GRID_KEY_WIDE
           : cy < row0   ? GRID_KEY_BELOW
           : cy > rowlast ? GRID_KEY_ABOVE
                          : h;
}

static void slice_keys(int32_t m, const float *restrict bx, const float *restrict by,
                       const float *restrict ux, const float *restrict uy, float k,
                       const grid_plan *g, int32_t row0, int32_t rowlast, int32_t spanx,
                       int32_t kshift, int32_t *restrict key, int32_t *restrict flag)
{
    /* A local copy of the plan: its fields read through g might alias the stores, which kept
     * gcc from vectorising the loop once the reach depended on g->sub. */
    const grid_plan gl = *g;
    for (int32_t p = 0; p < m; p++) {
        int32_t cx, cy, f;
        box_cells(slice_start(bx[p], ux[p], k), slice_start(by[p], uy[p], k), ux[p], uy[p], &gl,
                  &cx, &cy, &f);
        key[p] = item_key(cx, cy, f, row0, rowlast, spanx, gl.sub, kshift);
        flag[p] = f;
    }
}

/* Cells a numbered row holds (grid_bins' spanx): the columns, sub before them for the runs
 * that start left of a column, sub + 1 after. */
static uint64_t row_span(const grid_plan *g)
{
    return (uint64_t)g->gx + 2 * (uint64_t)g->sub + 1;
}

int grid_whole_keys_fit(const grid_plan *g)
{
    /* The whole grid as one band: rows 0 .. gy - 1, and one cell more for the end. */
    return (((uint64_t)g->gy * row_span(g) + 1) << keys_shift(g->sub)) + 2 <= INT32_MAX;
}

void grid_whole_keys(const grid_src *src, int32_t e0, int32_t e1, const grid_plan *g, float kf,
                     int32_t *restrict whole_key, int32_t *restrict whole_flag)
{
    slice_keys(e1 - e0, src->bx + e0, src->by + e0, src->ux + e0, src->uy + e0, kf, g, 0,
               g->gy - 1, (int32_t)row_span(g), keys_shift(g->sub), whole_key + e0,
               whole_flag + e0);
}

/* LSD radix sort of a[0, n) on bits [shift, shift + kb); returns the buffer holding the
 * result (a or tmp). Stable. */
static uint64_t *radix_sort(uint64_t *a, uint64_t *tmp, int32_t n, int shift, int kb,
                            uint32_t *hist)
{
    if (kb <= 0 || n < 2)
        return a;
    /* Digits of about log2(n) - 1 bits: the histogram stays smaller than the data. */
    int dmax = grid_bits_for((uint64_t)n) - 1;
    dmax = dmax < 6 ? 6 : dmax > GRID_RADIX_MAX_BITS ? GRID_RADIX_MAX_BITS : dmax;
    const int passes = (kb + dmax - 1) / dmax, d = (kb + passes - 1) / passes;
    const uint64_t mask = ((uint64_t)1 << d) - 1;
    for (int pass = 0; pass < passes; pass++) {
        const int sh = shift + pass * d;
        memset(hist, 0, ((size_t)1 << d) * sizeof *hist);
        for (int32_t i = 0; i < n; i++)
            hist[(a[i] >> sh) & mask]++;
        if (hist[(a[0] >> sh) & mask] == (uint32_t)n)
            continue;
        uint32_t sum = 0;
        for (uint64_t b = 0; b <= mask; b++) {
            const uint32_t c = hist[b];
            hist[b] = sum;
            sum += c;
        }
        for (int32_t i = 0; i < n; i++)
            tmp[hist[(a[i] >> sh) & mask]++] = a[i];
        uint64_t *t = a;
        a = tmp;
        tmp = t;
    }
    return a;
}

int32_t grid_lower_bound(const uint64_t *key, int32_t n, uint64_t v)
{
    int32_t lo = 0, hi = n;
    while (lo < hi) {
        const int32_t mid = lo + (hi - lo) / 2;
        if (key[mid] < v)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo;
}

/* The id of item e of the source. */
static inline int32_t src_id(const grid_src *src, int32_t e)
{
    return e < src->m ? (src->id ? src->id[e] : e) : src->wide[e - src->m];
}

/* a[e] into out[dest[e]] for e < m. */
static void scatter_f32(const float *restrict a, const int32_t *restrict dest, int32_t m,
                        float *restrict out)
{
    for (int32_t e = 0; e < m; e++)
        out[dest[e]] = a[e];
}

/* Every item e of the source into entry dest[e] of dst (its binning floats and id; an item
 * that is no entry has the thread's sink slot), then every entry's position at the start of
 * slice kf (what the prefilter reads), for the ne entries. Both sorts place so. An array at a
 * time: one loop that moved every array at once kept eleven pointers, which gcc spilled into
 * vector registers (45 instructions an entry). */
static void place_entries(const grid_src *src, const sim_world *w, const grid_plan *g,
                          float kf, const int32_t *restrict dest, int32_t ne,
                          grid_set *restrict dst)
{
    const int32_t m = src->m;
    scatter_f32(src->bx, dest, m, dst->bx), scatter_f32(src->by, dest, m, dst->by);
    scatter_f32(src->ux, dest, m, dst->ux), scatter_f32(src->uy, dest, m, dst->uy);
    int32_t *restrict id = dst->id;
    if (src->id) {
        const int32_t *restrict in = src->id;
        for (int32_t e = 0; e < m; e++)
            id[dest[e]] = in[e];
    } else {
        for (int32_t e = 0; e < m; e++)
            id[dest[e]] = e;
    }
    for (int32_t e = m; e < m + src->nwide; e++) {
        const int32_t p = src->wide[e - m], d = dest[e];
        const grid_particle q = grid_part(w, p);
        particle_f32(&q, g, &dst->bx[d], &dst->by[d], &dst->ux[d], &dst->uy[d]);
        id[d] = p;
    }
    const float *restrict bx = dst->bx, *restrict by = dst->by;
    const float *restrict ux = dst->ux, *restrict uy = dst->uy;
    float *restrict px = dst->px, *restrict py = dst->py;
    for (int32_t d = 0; d < ne; d++)
        px[d] = slice_start(bx[d], ux[d], kf), py[d] = slice_start(by[d], uy[d], kf);
}

/* Corner cells and flags of every item of the source in slice kf into th->cx0, th->cy0,
 * th->flag: the arrays vectorised, the few wide ones apart. */
static void item_cells(const grid_src *src, const sim_world *w, const grid_plan *g,
                       float kf, grid_thread *th)
{
    const int32_t m = src->m, items = src->m + src->nwide;
    slice_cells(m, src->bx, src->by, src->ux, src->uy, kf, g, th->cx0, th->cy0, th->flag);
    for (int32_t e = m; e < items; e++) {
        float bx, by, ux, uy;
        const grid_particle q = grid_part(w, src->wide[e - m]);
        particle_f32(&q, g, &bx, &by, &ux, &uy);
        box_cells(slice_start(bx, ux, kf), slice_start(by, uy, kf), ux, uy, g, &th->cx0[e],
                  &th->cy0[e], &th->flag[e]);
    }
}

/* The items count_whole chose placed: item sel[q] (of the source's arrays: no wide item) with
 * key key[q] and flags flag[q], q < entries, each with all its arrays at once into slot
 * pos[h + 1]++ (pos as after the counting sort's prefix sum), so that the items that are no
 * entry of the band cost nothing here; the same entries in the same slots as place_entries. */
static void place_chosen(const grid_src *src, float kf, grid_thread *th, grid_set *restrict dst,
                         int32_t *restrict pos, int32_t entries, int32_t kshift)
{
    const int32_t *restrict key = th->cx0, *restrict flag = th->flag, *restrict sel = th->cy0;
    int32_t *restrict scell = th->scell;
    uint8_t *restrict sext = th->sext;
    float *restrict bx = dst->bx, *restrict by = dst->by, *restrict ux = dst->ux;
    float *restrict uy = dst->uy;
    for (int32_t q = 0; q < entries; q++) {
        const int32_t h = key[q], e = sel[q], d = pos[h + 1]++;
        scell[d] = h >> kshift;
        sext[d] = (uint8_t)flag[q];
        bx[d] = src->bx[e], by[d] = src->by[e], ux[d] = src->ux[e], uy[d] = src->uy[e];
        dst->id[d] = src_id(src, e);
    }
    for (int32_t d = 0; d < entries; d++)
        dst->px[d] = slice_start(bx[d], ux[d], kf), dst->py[d] = slice_start(by[d], uy[d], kf);
}

/* A band's count from the whole grid's keys (grid_whole_keys) in one pass over the source's
 * items (no wide one among them): the band's rows are the whole keys in [lo, hi) (a row's keys
 * stay below the next row's), its key the whole key less row0's first. The entries are chosen
 * (th->cy0: the item; cx0 and flag: its band key and flags; in item order) and counted into
 * pos[h + 2], the wide listed, the items below the band counted. Returns the entries. */
static int32_t count_whole(const grid_src *src, const grid_bins *b, grid_thread *th,
                           int32_t *restrict pos, int32_t *restrict wide, int32_t *nw,
                           int32_t *below)
{
    const int32_t lo = (int32_t)(((uint64_t)b->row0 * b->spanx) << b->kshift);
    const int32_t hi = (int32_t)(((uint64_t)(b->rowlast + 1) * b->spanx) << b->kshift);
    const int32_t *restrict whole_key = src->whole_key, *restrict whole_flag = src->whole_flag;
    int32_t *restrict key = th->cx0, *restrict flag = th->flag, *restrict sel = th->cy0;
    int32_t q = 0, n_wide = 0, n_below = 0;
    for (int32_t e = 0; e < src->m; e++) {
        const int32_t h = whole_key[e];
        if (h >= lo && h < hi) {
            pos[h - lo + 2]++;
            key[q] = h - lo, flag[q] = whole_flag[e], sel[q] = e;
            q++;
        } else if (h == GRID_KEY_WIDE) {
            wide[n_wide++] = src_id(src, e);
        } else {
            n_below += h < lo;
        }
    }
    *nw = n_wide;
    *below = n_below;
    return q;
}

/* Dense: a counting sort on the keys (slice_keys), so that in every cell the entries reaching
 * further right come later. pos[h + 2] counts key h; after the prefix sum pos[h + 1] is where h
 * begins; the scatter advances it to where h ends, which leaves h's entries in [pos[h],
 * pos[h + 1]) and cell c's in [pos[c << kshift], pos[(c + 1) << kshift]). */
static void bin_dense(const grid_src *src, const sim_world *w, const grid_plan *g,
                      float kf, grid_thread *th, grid_set *restrict dst, int32_t *restrict wide,
                      grid_bins *b)
{
    const int32_t m = src->m, items = src->m + src->nwide, row0 = b->row0;
    const int32_t rowlast = b->rowlast, spanx = (int32_t)b->spanx;
    const int32_t kshift = b->kshift;
    const uint64_t keys = b->ncell << kshift;
    int32_t *restrict pos = th->pos;
    int32_t *restrict key = th->cx0, *restrict flag = th->flag;
    int32_t nw = 0, below = 0;
    memset(pos, 0, (size_t)(keys + 2) * sizeof *pos);
    if (src->whole_key && src->nwide == 0) {
        const int32_t entries = count_whole(src, b, th, pos, wide, &nw, &below);
        for (uint64_t c = 1; c < keys + 2; c++)
            pos[c] += pos[c - 1];
        place_chosen(src, kf, th, dst, pos, entries, kshift);
        b->ne = entries;
        b->nw = nw;
        b->below = below;
        b->nbase = pos[b->base_end << kshift];
        return;
    }
    slice_keys(m, src->bx, src->by, src->ux, src->uy, kf, g, row0, rowlast, spanx, kshift, key,
               flag);
    for (int32_t e = m; e < items; e++) {
        float bx, by, ux, uy;
        int32_t cx, cy;
        const grid_particle q = grid_part(w, src->wide[e - m]);
        particle_f32(&q, g, &bx, &by, &ux, &uy);
        box_cells(slice_start(bx, ux, kf), slice_start(by, uy, kf), ux, uy, g, &cx, &cy,
                  &flag[e]);
        key[e] = item_key(cx, cy, flag[e], row0, rowlast, spanx, g->sub, kshift);
    }
    for (int32_t e = 0; e < items; e++) {
        const int32_t h = key[e];
        if (h >= 0)
            pos[h + 2]++;
        else if (h == GRID_KEY_WIDE)
            wide[nw++] = src_id(src, e);
        else
            below += h == GRID_KEY_BELOW;
    }
    for (uint64_t c = 1; c < keys + 2; c++)
        pos[c] += pos[c - 1];
    /* Where each item goes (the thread's sink slot when it is no entry here), then the
     * entries' arrays one at a time (place_entries). */
    int32_t *restrict scell = th->scell, *restrict dest = th->cy0;
    uint8_t *restrict sext = th->sext;
    for (int32_t e = 0; e < items; e++) {
        const int32_t h = key[e];
        int32_t d = th->sink;
        if (h >= 0) {
            d = pos[h + 1]++;
            scell[d] = h >> kshift;
            sext[d] = (uint8_t)flag[e];
        }
        dest[e] = d;
    }
    place_entries(src, w, g, kf, dest, pos[keys], dst);
    b->ne = pos[keys];
    b->nw = nw;
    b->below = below;
    b->nbase = pos[b->base_end << kshift];
}

/* Sparse: radix words (cell, reach bits, index), sorted; the cell of each entry in th->skey. */
static void bin_sparse(const grid_src *src, const sim_world *w, const grid_plan *g,
                       float kf, grid_thread *th, grid_set *restrict dst, int32_t *restrict wide,
                       grid_bins *b)
{
    const int32_t items = src->m + src->nwide, row0 = b->row0, rowlast = b->rowlast;
    const uint64_t spanx = b->spanx;
    const int pbits = g->pbits, kshift = pbits + GRID_EXT_BITS;
    const uint64_t pmask = ((uint64_t)1 << pbits) - 1;
    int32_t ne = 0, nw = 0, below = 0;
    /* th->cy0 becomes where each item goes (place_entries) once its row is read: the sink slot
     * here, the entries' own after the sort. */
    int32_t *restrict dest = th->cy0;
    for (int32_t e = 0; e < items; e++) {
        const int32_t f = th->flag[e], cy = dest[e];
        dest[e] = th->sink;
        if (f & GRID_WIDE) {
            wide[nw++] = src_id(src, e);
        } else if (cy >= row0 && cy <= rowlast) {
            const uint64_t key =
                (uint64_t)(cy - row0) * spanx + (uint64_t)th->cx0[e] + (uint64_t)b->sub;
            th->ent[ne++] = key << kshift | (uint64_t)f << pbits | (uint64_t)e;
        } else {
            below += cy < row0;
        }
    }
    const uint64_t *restrict ent =
        radix_sort(th->ent, th->tmp, ne, kshift, grid_bits_for(b->ncell), th->hist);
    uint64_t *restrict skey = th->skey;
    uint8_t *restrict sext = th->sext;
    for (int32_t d = 0; d < ne; d++) {
        const uint64_t v = ent[d];
        dest[v & pmask] = d;
        skey[d] = v >> kshift;
        sext[d] = (uint8_t)(v >> pbits & ((1u << GRID_EXT_BITS) - 1));
    }
    place_entries(src, w, g, kf, dest, ne, dst);
    b->ne = ne;
    b->nw = nw;
    b->below = below;
    b->nbase = grid_lower_bound(th->skey, ne, b->base_end);
}

/* Entries [ne, ne + GRID_LANES) of z zeroed: the prefilter reads up to GRID_LANES - 1 slots past
 * a run's end, and its masked-off lanes stay finite. */
static void pad_entries(grid_set *z, int32_t ne)
{
    const size_t f = GRID_LANES * sizeof(float);
    memset(z->bx + ne, 0, f), memset(z->by + ne, 0, f), memset(z->ux + ne, 0, f);
    memset(z->uy + ne, 0, f), memset(z->px + ne, 0, f), memset(z->py + ne, 0, f);
    memset(z->id + ne, 0, GRID_LANES * sizeof(int32_t));
}

int grid_bin_slice(const grid_src *src, const sim_world *w, const grid_plan *g, float kf,
                   int32_t row0, int32_t row1, grid_thread *th, grid_set *dst, int32_t *wide,
                   grid_bins *b)
{
    b->row0 = row0;
    b->row1 = row1;
    /* Entries of the sub rows from row1 take part as upper neighbours of the band's rows. */
    b->sub = g->sub;
    b->kshift = keys_shift(b->sub);
    b->rowlast = b->row1 + b->sub - 1 < g->gy ? b->row1 + b->sub - 1 : g->gy - 1;
    b->spanx = row_span(g);
    /* Every cell a run of a base entry reaches, rows up to row1 + sub - 1 (empty where above
     * the grid), and one more for the end of the last. */
    b->ncell = (uint64_t)(b->row1 - b->row0 + b->sub) * b->spanx + 1;
    b->base_end = (uint64_t)(b->row1 - b->row0) * b->spanx;
    /* Dense while the keys are not many more than the items (and fit an int32_t). */
    const uint64_t keys = b->ncell << b->kshift;
    const uint64_t items = (uint64_t)src->m + (uint64_t)src->nwide;
    b->dense = keys + 2 <= INT32_MAX &&
               keys <= GRID_DENSE_CELLS_PER_PARTICLE * items + GRID_DENSE_CELLS_MIN;
    if (b->dense && grid_thread_reserve_keys(th, keys))
        return -1;
    if (b->dense) {
        bin_dense(src, w, g, kf, th, dst, wide, b);
    } else {
        item_cells(src, w, g, kf, th);
        bin_sparse(src, w, g, kf, th, dst, wide, b);
    }
    pad_entries(dst, b->ne);
    return 0;
}
