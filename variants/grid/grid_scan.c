/*
 * grid_scan.c: the slices of a step, binned (grid_binning.c) and scanned (grid_runs.c). One
 * thread bins each slice from the previous slice's entries, already in nearly the right order.
 * A team cuts every slice into bands of rows, one a thread, with as many of the source's items
 * each: the threads split the source (the previous slice's entries in cell order) into the
 * bands' items, then each bins its band, lends it to the team where every thread has a band
 * (its threads scan chunks of every band's runs, their own first) and writes its base entries
 * back in cell order, the next slice's source. A thread so holds about N / T items, whatever T.
 */
#include <sched.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>

#include <omp.h>

#include "grid.h"

/* The end of a band's slice, its entries' runs looked at (`tests` pairs): its wide boxes against
 * its entries, the wide boxes' pairs of rows first, first + stride, ..., the queue decided, the
 * counts for --timing. */
static void end_slice(const grid_ctx *cx, const grid_thread *th, const grid_set *dst,
                      const int32_t *wide, const grid_bins *b, uint64_t tests, int first,
                      int stride)
{
    tests += grid_runs_wide(cx, th, dst, wide, b);
    tests += grid_wide_pairs(cx, wide, b->nw, first, stride);
    grid_queue_flush(cx);
    cx->buf->pair_tests += tests;
    cx->buf->chunks++;
}

/* Slice cx->k of the rows [row0, row1): bin src into th->set[out] / th->wide[out] (*b says
 * what came out) and look at every pair of the band once; the wide boxes' pairs of rows
 * first, first + stride, ... Returns 0, or -1 when memory is short. */
static int run_slice(const grid_ctx *cx, grid_thread *th, int32_t row0, int32_t row1, int first,
                     int stride, const grid_src *src, int out, grid_bins *b)
{
    grid_set *dst = &th->set[out];
    int32_t *wide = th->wide[out];
    if (grid_bin_slice(src, cx->w, cx->g, (float)cx->k, row0, row1, th, dst, wide, b))
        return -1;
    const uint64_t tests = b->dense ? grid_runs_dense(cx, th, dst, b, 0, b->nbase)
                                    : grid_runs_sparse(cx, th, dst, b);
    end_slice(cx, th, dst, wide, b, tests, first, stride);
    return 0;
}

/* Whether this finder's share of the step's slices is empty (fewer slices than parts: see
 * grid_scratch's slice_parts); then thread 0 keeps the particles' order for the next step. */
static bool no_slices(grid_scratch *s, const grid_plan *g, int me)
{
    if (g->k0 < g->K)
        return false;
    if (me == 0)
        memcpy(s->ord_next, s->ord, (size_t)s->n * sizeof *s->ord);
    return true;
}

void grid_run_alone(const sim_world *w, grid_scratch *s, const grid_plan *g, sim_cand_buf *buf)
{
    grid_thread *th = &s->th[0];
    if (no_slices(s, g, 0))
        return;
    /* On every slice of the step, each slice is binned from the one before (its entries are
     * almost in the next one's order), the two in sets used in turn. A share of the slices
     * (kstep > 1) bins each from the step's start, S, into one set: its slices are kstep apart,
     * where the slice before helps less, and the second set would be N items (28 bytes each)
     * more on every mpi rank. */
    const bool chain = g->kstep == 1;
    if (grid_thread_reserve(th, s->n, chain ? 2 : 1)) {
        buf->failed = true;
        return;
    }
    const grid_src start = {.bx = s->bx, .by = s->by, .ux = s->ux, .uy = s->uy, .id = s->ord,
                            .m = s->n, .wide = NULL, .nwide = 0};
    grid_src src = start;
    grid_queue queue = {.at = 0, .len = 0, .on = s->n > GRID_SMALL_N};
    int out = 0;
    for (int k = g->k0; k < g->K; k += g->kstep) {
        const grid_ctx cx = {.w = w, .s = s, .g = g, .k = k, .buf = buf, .queue = &queue};
        grid_bins b;
        if (run_slice(&cx, th, 0, g->gy, 0, 1, &src, out, &b)) {
            buf->failed = true;
            return;
        }
        const grid_set *z = &th->set[out];
        if (k + g->kstep >= g->K) {
            /* Every particle once, in this slice's cell order: the next step's start. */
            memcpy(s->ord_next, z->id, (size_t)b.nbase * sizeof(int32_t));
            memcpy(s->ord_next + (s->n - b.nw), th->wide[out], (size_t)b.nw * sizeof(int32_t));
        }
        if (chain) {
            src = (grid_src){.bx = z->bx, .by = z->by, .ux = z->ux, .uy = z->uy, .id = z->id,
                             .m = b.ne, .wide = th->wide[out], .nwide = b.nw};
            out ^= 1;
        }
    }
}

/* The source's item e in slice kf: its corner row, and whether it is wide. */
static inline int32_t item_row(const grid_scratch *s, const grid_plan *g, int32_t e, float kf,
                               int32_t *flag)
{
    int32_t cx, cy;
    box_cells(slice_start(s->bx[e], s->ux[e], kf), slice_start(s->by[e], s->uy[e], kf), s->ux[e],
              s->uy[e], g, &cx, &cy, flag);
    return cy;
}

static int row_cmp(const void *a, const void *b)
{
    const int32_t x = *(const int32_t *)a, y = *(const int32_t *)b;
    return (x > y) - (x < y);
}

/* The bands' first rows in slice kf, at quantiles of the rows of GRID_BAND_SAMPLES items a band
 * spread evenly over the source: the bands then hold about as many items each, whatever order
 * the source is in (the first step's is the particles'). Every thread computes the same. */
static void band_bounds(const grid_scratch *s, const grid_plan *g, float kf, int bands,
                        grid_thread *th)
{
    const int32_t m = GRID_BAND_SAMPLES * bands;
    int32_t *row = th->sample;
    for (int32_t q = 0; q < m; q++) {
        int32_t f;
        row[q] = item_row(s, g, (int32_t)(((int64_t)s->n * (2 * q + 1)) / (2 * m)), kf, &f);
    }
    qsort(row, (size_t)m, sizeof *row, row_cmp);
    th->bound[0] = 0;
    for (int b = 1; b < bands; b++)
        th->bound[b] = row[(int64_t)m * b / bands];
    th->bound[bands] = g->gy;
}

/* The band whose rows hold row: the last b with bound[b] <= row (never an empty one). */
static inline int band_of(const int32_t *bound, int bands, int32_t row)
{
    int lo = 0, hi = bands - 1;
    while (lo < hi) {
        const int mid = (lo + hi + 1) / 2;
        if (bound[mid] <= row)
            lo = mid;
        else
            hi = mid - 1;
    }
    return lo;
}

/* Whether band u (below the band of `row`) takes an item of `row` as an upper neighbour: its
 * rows look sub rows up (grid_bins' rowlast). */
static inline int neighbour_of(const int32_t *bound, int u, int32_t row, int32_t sub)
{
    return bound[u + 1] + sub - 1 >= row;
}

/* Count this thread's share of the source [p0, p1) into the bands: cnt[2 b] items of band b,
 * cnt[2 b + 1] of them base entries, cnt[2 bands] wide particles; each item's row and band
 * kept for the split. */
static void count_part(const grid_scratch *s, const grid_plan *g, float kf, int bands,
                       grid_thread *th, int32_t p0, int32_t p1, int32_t *cnt)
{
    const int32_t *bound = th->bound;
    memset(cnt, 0, (2 * (size_t)bands + 1) * sizeof *cnt);
    for (int32_t e = p0; e < p1; e++) {
        int32_t f;
        const int32_t row = item_row(s, g, e, kf, &f);
        if (f & GRID_WIDE) {
            th->prow[e - p0] = -1;
            cnt[2 * bands]++;
            continue;
        }
        const int b = band_of(bound, bands, row);
        th->prow[e - p0] = row;
        th->pband[e - p0] = b;
        cnt[2 * b] += 1, cnt[2 * b + 1] += 1;
        for (int u = b - 1; u >= 0 && neighbour_of(bound, u, row, g->sub); u--)
            cnt[2 * u] += bound[u] < bound[u + 1];
    }
}

/* Item e of the source into slot d of the bands' items. */
static inline void put_item(const grid_scratch *s, int32_t e, int32_t d)
{
    const grid_team *t = &s->team;
    t->bx[d] = s->bx[e], t->by[d] = s->by[e], t->ux[d] = s->ux[e], t->uy[d] = s->uy[e];
    t->id[d] = s->ord[e];
}

/* Split this thread's share of the source into the bands' items (and the wide list), at the
 * places the counts of all threads give. */
static void split_part(grid_scratch *s, const grid_plan *g, int bands, int team, int me,
                       grid_thread *th, int32_t p0, int32_t p1)
{
    const int32_t stride = GRID_COUNT_STRIDE(team);
    const int32_t *count = s->team.count, *bound = th->bound;
    int32_t *cur = th->cur, at = 0, wide_at = 0;
    for (int b = 0; b < bands; b++) {
        cur[b] = at;
        for (int t = 0; t < team; t++) {
            if (t < me)
                cur[b] += count[t * stride + 2 * b];
            at += count[t * stride + 2 * b];
        }
    }
    for (int t = 0; t < me; t++)
        wide_at += count[t * stride + 2 * bands];
    for (int32_t e = p0; e < p1; e++) {
        const int32_t row = th->prow[e - p0];
        if (row < 0) {
            s->team.wide[wide_at++] = s->ord[e];
            continue;
        }
        const int b = th->pband[e - p0];
        put_item(s, e, cur[b]++);
        for (int u = b - 1; u >= 0 && neighbour_of(bound, u, row, g->sub); u--)
            if (bound[u] < bound[u + 1])
                put_item(s, e, cur[u]++);
    }
}

/* Band `me`'s base entries (z's first nbase) back into the source at `at`, in cell order, and
 * their ids into ids (the source's, or the next step's order after the last slice); band 0
 * also puts the wide particles at the end. */
static void write_back(const sim_world *w, grid_scratch *s, const grid_plan *g, const grid_set *z, int32_t nbase,
                       int32_t at, int me, int32_t nwide, int32_t *ids)
{
    memcpy(s->bx + at, z->bx, (size_t)nbase * sizeof(float));
    memcpy(s->by + at, z->by, (size_t)nbase * sizeof(float));
    memcpy(s->ux + at, z->ux, (size_t)nbase * sizeof(float));
    memcpy(s->uy + at, z->uy, (size_t)nbase * sizeof(float));
    memcpy(ids + at, z->id, (size_t)nbase * sizeof(int32_t));
    if (me != 0)
        return;
    for (int32_t q = 0; q < nwide; q++) {
        const int32_t e = s->n - nwide + q, p = s->team.wide[q];
        const grid_particle q = grid_part(w, p);
        particle_f32(&q, g, &s->bx[e], &s->by[e], &s->ux[e], &s->uy[e]);
        ids[e] = p;
    }
}

/* Slice cx->k of band `me` of a team that lends its bands (grid_run_direct from the team's whole
 * keys, grid_run_team from the band's items): bin the band's rows [row0, row1) into th->set[0]
 * (*b), lend it (slice number `slice`), then look at the runs of chunks of base entries claimed
 * from every lent band, this thread's first, until none is left, so that a thread done early takes
 * over part of a slow one's band; then the band's wide boxes. The band is lent even when it failed
 * or is sparse, with no entries to claim, so that no thread waits for it. Returns 0, or -1 when
 * memory is short. */
static int run_slice_lent(const grid_ctx *cx, grid_scratch *s, grid_thread *th, int me,
                          int bands, uint32_t slice, bool failed, const grid_src *src,
                          grid_bins *b)
{
    grid_set *dst = &th->set[0];
    int32_t *wide = th->wide[0];
    const int bad = failed || grid_bin_slice(src, cx->w, cx->g, (float)cx->k, th->bound[me],
                                             th->bound[me + 1], th, dst, wide, b);
    grid_band_share *mine = &s->team.share[me];
    /* Nothing to claim where it failed (*b unset) or is sparse (runs only its owner reads). */
    mine->b = bad ? (grid_bins){.nbase = 0} : *b;
    if (!bad && !b->dense)
        mine->b.nbase = 0;
    __atomic_store_n(&mine->next, 0, __ATOMIC_RELAXED);
    __atomic_store_n(&mine->ready, slice, __ATOMIC_RELEASE);
    uint64_t tests = 0;
    for (;;) {
        bool left = false, took = false;
        for (int i = 0; i < bands; i++) {
            grid_band_share *lent = &s->team.share[(me + i) % bands];
            if (__atomic_load_n(&lent->ready, __ATOMIC_ACQUIRE) != slice) {
                left = true; /* its owner is still binning: come back to it */
                continue;
            }
            const grid_thread *owner = &s->th[(me + i) % bands];
            for (;;) {
                const int32_t a0 = GRID_RUN_CHUNK * __atomic_fetch_add(&lent->next, 1,
                                                                       __ATOMIC_RELAXED);
                if (a0 >= lent->b.nbase)
                    break;
                const int32_t a1 = a0 + GRID_RUN_CHUNK < lent->b.nbase ? a0 + GRID_RUN_CHUNK
                                                                       : lent->b.nbase;
                tests += grid_runs_dense(cx, owner, &owner->set[0], &lent->b, a0, a1);
                took = true;
            }
        }
        if (!left)
            break;
        /* An owner still binning may be descheduled (more threads than CPUs): let it run. */
        if (!took)
            sched_yield();
    }
    if (bad)
        return -1;
    if (!b->dense)
        tests += grid_runs_sparse(cx, th, dst, b);
    end_slice(cx, th, dst, wide, b, tests, me, bands);
    return 0;
}

void grid_run_team(const sim_world *w, grid_scratch *s, const grid_plan *g, int me, int team,
                   sim_cand_buf *buf)
{
    grid_thread *th = &s->th[me];
    if (no_slices(s, g, me))
        return;
    /* The runtime may give fewer threads than asked. */
    const int bands = g->bands < team ? g->bands : team;
    /* Where every thread has a band, each band is lent to the team once binned, so that a
     * thread whose core is slower or whose band is larger is helped. */
    const bool lend = bands == team;
    const int32_t stride = GRID_COUNT_STRIDE(team);
    const int32_t p0 = (int32_t)((int64_t)s->n * me / team);
    const int32_t p1 = (int32_t)((int64_t)s->n * (me + 1) / team);
    /* Memory short: this thread stops working but keeps meeting the team's barriers. */
    bool failed = grid_thread_reserve_part(th, p1 - p0) != 0;
    grid_queue queue = {.at = 0, .len = 0, .on = s->n > GRID_SMALL_N};
    for (int k = g->k0; k < g->K; k += g->kstep) {
        const float kf = (float)k;
        double t0 = sim_busy_start();
        band_bounds(s, g, kf, bands, th);
        int32_t *cnt = s->team.count + (size_t)me * (size_t)stride;
        if (!failed)
            count_part(s, g, kf, bands, th, p0, p1, cnt);
        else
            memset(cnt, 0, (size_t)stride * sizeof *cnt);
        sim_busy_stop(buf, t0);
#pragma omp barrier
        t0 = sim_busy_start();
        if (!failed)
            split_part(s, g, bands, team, me, th, p0, p1);
        /* This band's items and place in the source; the wide particles. */
        int32_t items = 0, first = 0, base_at = 0, nwide = 0;
        for (int t = 0; t < team; t++) {
            const int32_t *c = s->team.count + (size_t)t * (size_t)stride;
            nwide += c[2 * bands];
            for (int b = 0; b < bands; b++) {
                if (b < me)
                    first += c[2 * b], base_at += c[2 * b + 1];
                else if (b == me)
                    items += c[2 * b];
            }
        }
        sim_busy_stop(buf, t0);
#pragma omp barrier
        t0 = sim_busy_start();
        if (me < bands && (lend || !failed)) {
            if (!failed)
                failed = grid_thread_reserve(th, items + nwide, 1) != 0;
            const grid_team *tm = &s->team;
            const grid_src src = {.bx = tm->bx + first, .by = tm->by + first,
                                  .ux = tm->ux + first, .uy = tm->uy + first,
                                  .id = tm->id + first, .m = items, .wide = tm->wide,
                                  .nwide = nwide};
            const grid_ctx cx = {.w = w, .s = s, .g = g, .k = k, .buf = buf, .queue = &queue};
            grid_bins b;
            if (lend)
                /* Every band is lent, failed or not: the others wait for each band. */
                failed = run_slice_lent(&cx, s, th, me, bands, ++th->slices, failed, &src,
                                        &b) != 0;
            else if (!failed)
                failed = run_slice(&cx, th, th->bound[me], th->bound[me + 1], me, bands, &src, 0,
                                   &b) != 0;
            if (!failed)
                write_back(w, s, g, &th->set[0], b.nbase, base_at, me, nwide,
                           k + g->kstep >= g->K ? s->ord_next : s->ord);
        }
        sim_busy_stop(buf, t0);
#pragma omp barrier
    }
    if (failed)
        buf->failed = true;
}

void grid_run_direct(const sim_world *w, grid_scratch *s, const grid_plan *g, int me, int team,
                     sim_cand_buf *buf)
{
    grid_thread *th = &s->th[me];
    const int bands = g->bands < team ? g->bands : team;
    /* The team shares each slice's keys out where it is big enough to have their arrays, and
     * every thread has a band (all meet the barrier). */
    const bool whole = s->team.whole_key[0] && bands == team && grid_whole_keys_fit(g);
    if (no_slices(s, g, me) || me >= bands)
        return;
    if (grid_thread_reserve(th, s->n, 1))
        buf->failed = true; /* keeps meeting the team's barriers, doing nothing */
    /* The plan's floats stay the source of every slice (a slice only moves where they land). */
    grid_src src = {.bx = s->bx, .by = s->by, .ux = s->ux, .uy = s->uy, .id = s->ord, .m = s->n,
                    .wide = NULL, .nwide = 0, .whole_key = NULL, .whole_flag = NULL};
    grid_queue queue = {.at = 0, .len = 0, .on = s->n > GRID_SMALL_N};
    const int32_t p0 = (int32_t)((int64_t)s->n * me / team);
    const int32_t p1 = (int32_t)((int64_t)s->n * (me + 1) / team);
    for (int k = g->k0; k < g->K; k += g->kstep) {
        double t0 = sim_busy_start();
        if (whole) {
            src.whole_key = s->team.whole_key[k & 1], src.whole_flag = s->team.whole_flag[k & 1];
            grid_whole_keys(&src, p0, p1, g, (float)k, s->team.whole_key[k & 1],
                            s->team.whole_flag[k & 1]);
            sim_busy_stop(buf, t0);
            /* Slice k + 1 writes the other arrays; slice k + 2 writes these again only after
             * this barrier of slice k + 1, which every thread meets after its slice k. */
#pragma omp barrier
            t0 = sim_busy_start();
        }
        band_bounds(s, g, (float)k, bands, th);
        const grid_ctx cx = {.w = w, .s = s, .g = g, .k = k, .buf = buf, .queue = &queue};
        grid_bins b;
        if (whole) {
            /* Every thread lends its band, failed or not: the others wait for each band. */
            if (run_slice_lent(&cx, s, th, me, bands, ++th->slices, buf->failed, &src, &b))
                buf->failed = true;
        } else if (!buf->failed && run_slice(&cx, th, th->bound[me], th->bound[me + 1], me,
                                             bands, &src, 0, &b)) {
            buf->failed = true;
        }
        if (!buf->failed && k + g->kstep >= g->K) {
            /* The bands' base entries in band order, then the wide particles: every particle
             * once, in this slice's cell order, the next step's start. */
            memcpy(s->ord_next + b.below, th->set[0].id, (size_t)b.nbase * sizeof(int32_t));
            if (me == 0)
                memcpy(s->ord_next + (s->n - b.nw), th->wide[0], (size_t)b.nw * sizeof(int32_t));
        }
        sim_busy_stop(buf, t0);
    }
}
