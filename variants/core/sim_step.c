/*
 * sim_step.c: one step of SPEC §2, shared by every variant.
 *
 *   1. wall candidates (one buffer per thread; found by the step before's motion loop, or here
 *      for a first step) and pair candidates (the variant's finder, into per-writer buffers);
 *   2. merge and sort by the total key (t, pair before wall, i, j);
 *   3. one greedy walk accepts a candidate when neither particle has been accepted yet;
 *   4. every particle moves exactly once, reading the old state and writing a new one, so the
 *      motion loop can run in parallel without races and with thread-independent results; the
 *      new state's wall candidates are found right after, in the same region, for the next step.
 *
 * Why per-writer buffers and not the seed's shared array behind `omp critical`: the critical
 * section serialised every candidate append (the report's bottleneck), and the order in which
 * threads entered it was the order candidates were found, which is not reproducible. Private
 * buffers need no lock; the sort makes the order irrelevant.
 */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include <omp.h>

#include "sim_core.h"

/* event[] of a particle with no accepted collision this step. */
#define SIM_EVENT_NONE ((int32_t)-2)

/* Below this many particles the per-particle loops (wall times, motion) are not worth a
 * parallel region. */
#define SIM_PARALLEL_MIN 4096

struct sim_stepper {
    const sim_variant *variant;
    int threads;
    bool parallel;
    sim_pair_sink sink;
    sim_cand_buf *walls; /* the wall candidates of the world's state, one buffer per thread */
    bool walls_ready;    /* walls were found by the last step's motion loop (see sim_step) */
    sim_cand *merged, *merged_tmp; /* the sorted list and the radix sort's other buffer */
    size_t merged_cap, merged_tmp_cap;
    int32_t *event;    /* accepted event per particle: SIM_EVENT_NONE, SIM_WALL or the partner */
    sim_real *event_t; /* its time */
    sim_real *nx, *ny, *nvx, *nvy; /* the next state, swapped with the world's arrays */
    uint64_t *writer_pairs;        /* pair tests per candidate buffer over the run */
};

/* Time for a centre at q moving at w to reach the wall ahead (SPEC §2); infinite when w == 0. */
static inline sim_real axis_time(sim_real q, sim_real w, sim_real lo, sim_real hi)
{
    if (w > 0)
        return (hi - q) / w;
    if (w < 0)
        return (lo - q) / w;
    return SIM_REAL_INF;
}

/* The wall a centre moving at w reaches. */
static inline sim_real axis_wall(sim_real w, sim_real lo, sim_real hi)
{
    return w > 0 ? hi : lo;
}

static inline sim_real clamp(sim_real q, sim_real lo, sim_real hi)
{
    return q < lo ? lo : (q > hi ? hi : q);
}

/* SPEC §2 wall time of a centre at (x, y) moving at (vx, vy). */
static inline sim_real wall_time(sim_real x, sim_real y, sim_real vx, sim_real vy, sim_real lo,
                                 sim_real hi)
{
    const sim_real tx = axis_time(x, vx, lo, hi), ty = axis_time(y, vy, lo, hi);
    return tx < ty ? tx : ty;
}

sim_real sim_wall_time(const sim_world *w, int32_t i)
{
    return wall_time(w->x[i], w->y[i], w->vx[i], w->vy[i], w->lo, w->hi);
}

/* A particle that has had its collision moves on for `rest` of the step; a wall it meets now
 * stops it there (SPEC: seed assumption 3), keeping its velocity, until the next step. */
static void finish(sim_real *x, sim_real *y, sim_real vx, sim_real vy, sim_real rest,
                   sim_real lo, sim_real hi)
{
    sim_real tx = axis_time(*x, vx, lo, hi), ty = axis_time(*y, vy, lo, hi);
    if (tx < 0) /* rounding can put the centre a hair past the wall it moves towards */
        tx = 0;
    if (ty < 0)
        ty = 0;
    const sim_real tw = tx < ty ? tx : ty;
    if (tw < rest) {
        *x += tw * vx;
        *y += tw * vy;
        if (tx == tw)
            *x = axis_wall(vx, lo, hi);
        if (ty == tw)
            *y = axis_wall(vy, lo, hi);
    } else {
        *x += rest * vx;
        *y += rest * vy;
    }
}

static bool buf_reserve(sim_cand **items, size_t *cap, size_t need)
{
    if (need <= *cap)
        return true;
    size_t c = *cap ? *cap : 1;
    while (c < need)
        c *= 2;
    sim_cand *p = realloc(*items, c * sizeof *p);
    if (!p)
        return false;
    *items = p;
    *cap = c;
    return true;
}

sim_stepper *sim_stepper_create(const sim_world *w, const sim_variant *v, int threads)
{
    sim_stepper *s = calloc(1, sizeof *s);
    if (!s)
        return NULL;
    s->variant = v;
    s->threads = v->parallel ? threads : 1;
    s->parallel = v->parallel && threads > 1;
    int count = v->buffer_count ? v->buffer_count(s->threads) : s->threads;
    if (count < 1)
        count = 1;
    s->sink.count = count;
    s->sink.threads = s->threads;
    /* sizeof(sim_cand_buf) is a multiple of its 64-byte alignment, as aligned_alloc needs. */
    s->sink.bufs = aligned_alloc(_Alignof(sim_cand_buf), (size_t)count * sizeof(sim_cand_buf));
    s->walls = aligned_alloc(_Alignof(sim_cand_buf), (size_t)s->threads * sizeof(sim_cand_buf));
    const size_t n = (size_t)w->n;
    s->event = malloc(n * sizeof *s->event + 1);
    s->event_t = malloc(n * sizeof *s->event_t + 1);
    s->nx = malloc(n * sizeof(sim_real) + 1);
    s->ny = malloc(n * sizeof(sim_real) + 1);
    s->nvx = malloc(n * sizeof(sim_real) + 1);
    s->nvy = malloc(n * sizeof(sim_real) + 1);
    s->writer_pairs = calloc((size_t)count, sizeof *s->writer_pairs);
    if (!s->sink.bufs || !s->walls || !s->event || !s->event_t || !s->nx || !s->ny || !s->nvx ||
        !s->nvy || !s->writer_pairs) {
        sim_stepper_destroy(s);
        return NULL;
    }
    memset(s->sink.bufs, 0, (size_t)count * sizeof(sim_cand_buf));
    memset(s->walls, 0, (size_t)s->threads * sizeof(sim_cand_buf));
    if (s->parallel)
        sim_team_spread(s->threads);
    if (v->scratch_create) {
        s->sink.scratch = v->scratch_create(w, s->threads);
        if (!s->sink.scratch) {
            sim_stepper_destroy(s);
            return NULL;
        }
    }
    return s;
}

void sim_stepper_destroy(sim_stepper *s)
{
    if (!s)
        return;
    if (s->sink.scratch && s->variant->scratch_destroy)
        s->variant->scratch_destroy(s->sink.scratch);
    if (s->sink.bufs)
        for (int k = 0; k < s->sink.count; k++)
            free(s->sink.bufs[k].items);
    free(s->sink.bufs);
    if (s->walls)
        for (int k = 0; k < s->threads; k++)
            free(s->walls[k].items);
    free(s->walls);
    free(s->merged);
    free(s->merged_tmp);
    free(s->event);
    free(s->event_t);
    free(s->nx);
    free(s->ny);
    free(s->nvx);
    free(s->nvy);
    free(s->writer_pairs);
    free(s);
}

int sim_stepper_writers(const sim_stepper *s)
{
    return s->sink.count;
}

sim_thread_work sim_stepper_work(const sim_stepper *s, int k)
{
    return (sim_thread_work){.busy_s = s->sink.bufs[k].busy_s,
                             .pairs = s->writer_pairs[k],
                             .chunks = s->sink.bufs[k].chunks};
}

/* The SPEC §2 key: t ascending; pair before wall; smaller i; smaller j. Total, so qsort's
 * instability cannot show. */
static int cand_cmp(const void *pa, const void *pb)
{
    const sim_cand *a = pa, *b = pb;
    if (a->t < b->t)
        return -1;
    if (a->t > b->t)
        return 1;
    const int a_wall = a->j == SIM_WALL, b_wall = b->j == SIM_WALL;
    if (a_wall != b_wall)
        return a_wall - b_wall;
    if (a->i != b->i)
        return a->i < b->i ? -1 : 1;
    if (a->j != b->j)
        return a->j < b->j ? -1 : 1;
    return 0;
}

/* An unsigned image of t whose order is t's (for every real type: the conversion to double is
 * monotone, so t < t' gives key <= key'); -0.0 is made +0.0 first, as the comparison treats
 * them. */
static inline uint64_t cand_key(sim_real t)
{
    const double d = (double)t + 0.0;
    uint64_t b;
    memcpy(&b, &d, sizeof b);
    return b >> 63 ? ~b : b | UINT64_C(1) << 63;
}

/* The radix sort orders the top SIM_RADIX_PASSES * SIM_RADIX_BITS = 33 bits of cand_key: sign,
 * exponent and 21 bits of mantissa, a relative resolution of 2^-21. A step's few thousand
 * times rarely share them, and the runs that do are finished by cand_cmp; three passes instead
 * of the six that the whole key takes. */
#define SIM_RADIX_BITS 11
#define SIM_RADIX_PASSES 3
#define SIM_RADIX_BUCKETS (1u << SIM_RADIX_BITS)
#define SIM_RADIX_LOW (64 - SIM_RADIX_PASSES * SIM_RADIX_BITS) /* key bits left to cand_cmp */

/* Sort a[0, n) by cand_cmp: an LSD radix sort on the top bits of cand_key (stable, O(n); a
 * step's few thousand candidates took 0.6 ms in qsort's merge sort, longer than grid's binning
 * of a slice), then cand_cmp on the runs of equal top bits (close or tied times, or f128 times
 * equal in double), which are rare and short. tmp holds n items. */
void sim_sort_candidates(sim_cand *a, sim_cand *tmp, size_t n)
{
    if (n < 2)
        return;
    uint32_t hist[SIM_RADIX_PASSES][SIM_RADIX_BUCKETS];
    memset(hist, 0, sizeof hist);
    for (size_t k = 0; k < n; k++) {
        const uint64_t key = cand_key(a[k].t);
        for (int p = 0; p < SIM_RADIX_PASSES; p++)
            hist[p][key >> (SIM_RADIX_LOW + p * SIM_RADIX_BITS) & (SIM_RADIX_BUCKETS - 1)]++;
    }
    sim_cand *src = a, *dst = tmp;
    for (int p = 0; p < SIM_RADIX_PASSES; p++) {
        const int shift = SIM_RADIX_LOW + p * SIM_RADIX_BITS;
        uint32_t *h = hist[p];
        if (h[cand_key(src[0].t) >> shift & (SIM_RADIX_BUCKETS - 1)] == n)
            continue; /* one digit value: this pass would not move anything */
        uint32_t sum = 0;
        for (unsigned b = 0; b < SIM_RADIX_BUCKETS; b++) {
            const uint32_t c = h[b];
            h[b] = sum;
            sum += c;
        }
        for (size_t k = 0; k < n; k++)
            dst[h[cand_key(src[k].t) >> shift & (SIM_RADIX_BUCKETS - 1)]++] = src[k];
        sim_cand *t = src;
        src = dst;
        dst = t;
    }
    if (src != a)
        memcpy(a, src, n * sizeof *a);
    for (size_t lo = 0; lo < n;) {
        const uint64_t top = cand_key(a[lo].t) >> SIM_RADIX_LOW;
        size_t hi = lo + 1;
        while (hi < n && cand_key(a[hi].t) >> SIM_RADIX_LOW == top)
            hi++;
        if (hi - lo > 1)
            qsort(a + lo, hi - lo, sizeof *a, cand_cmp);
        lo = hi;
    }
}

static void clear_walls(sim_stepper *s)
{
    for (int k = 0; k < s->threads; k++)
        s->walls[k].len = 0;
}

/* Push a wall candidate of the state (x, y, vx, vy) of particle i when it falls within the
 * step. */
static inline void push_wall(sim_cand_buf *buf, sim_real x, sim_real y, sim_real vx, sim_real vy,
                             sim_real lo, sim_real hi, int32_t i)
{
    const sim_real tw = wall_time(x, y, vx, vy, lo, hi);
    if (tw <= 1)
        sim_cand_push(buf, tw, i, SIM_WALL);
}

/* The wall candidates of the world's state, for a first step; later steps get them from the
 * motion loop of the step before. */
static void find_walls(sim_stepper *s, const sim_world *w)
{
    const int32_t n = w->n;
    clear_walls(s);
#pragma omp parallel num_threads(s->threads) if (s->parallel && n >= SIM_PARALLEL_MIN)
    {
        sim_cand_buf *buf = &s->walls[omp_get_thread_num()];
#pragma omp for schedule(static)
        for (int32_t i = 0; i < n; i++)
            push_wall(buf, w->x[i], w->y[i], w->vx[i], w->vy[i], w->lo, w->hi, i);
    }
}

static void append_items(sim_cand *dst, size_t *at, const sim_cand_buf *buf)
{
    if (buf->len == 0)
        return;
    memcpy(dst + *at, buf->items, buf->len * sizeof(sim_cand));
    *at += buf->len;
}

/* Gather the wall buffer and every finder buffer into one sorted list. Returns its length, or
 * (size_t)-1 when memory ran out. */
static size_t merge_candidates(sim_stepper *s, sim_stats *stats)
{
    size_t total = 0;
    bool failed = false;
    for (int k = 0; k < s->threads; k++) {
        total += s->walls[k].len;
        failed |= s->walls[k].failed;
    }
    for (int k = 0; k < s->sink.count; k++) {
        total += s->sink.bufs[k].len;
        failed |= s->sink.bufs[k].failed;
        stats->pair_tests += s->sink.bufs[k].pair_tests;
        s->writer_pairs[k] += s->sink.bufs[k].pair_tests;
        s->sink.bufs[k].pair_tests = 0;
    }
    if (failed || !buf_reserve(&s->merged, &s->merged_cap, total) ||
        !buf_reserve(&s->merged_tmp, &s->merged_tmp_cap, total))
        return (size_t)-1;
    /* An empty buffer may never have been allocated: memcpy and qsort must not see its NULL
     * pointer, even for zero items (undefined behaviour, and UBSan stops the run). */
    size_t at = 0;
    for (int k = 0; k < s->threads; k++)
        append_items(s->merged, &at, &s->walls[k]);
    for (int k = 0; k < s->sink.count; k++) {
        append_items(s->merged, &at, &s->sink.bufs[k]);
        s->sink.bufs[k].len = 0;
    }
    sim_sort_candidates(s->merged, s->merged_tmp, total);
    stats->candidates += total;
    return total;
}

static void resolve(sim_stepper *s, int32_t n, size_t count, sim_stats *stats)
{
    for (int32_t i = 0; i < n; i++)
        s->event[i] = SIM_EVENT_NONE;
    for (size_t k = 0; k < count; k++) {
        const sim_cand c = s->merged[k];
        if (s->event[c.i] != SIM_EVENT_NONE)
            continue;
        if (c.j == SIM_WALL) {
            s->event[c.i] = SIM_WALL;
            s->event_t[c.i] = c.t;
            stats->wall_collisions++;
        } else if (s->event[c.j] == SIM_EVENT_NONE) {
            s->event[c.i] = c.j;
            s->event[c.j] = c.i;
            s->event_t[c.i] = c.t;
            s->event_t[c.j] = c.t;
            stats->pair_collisions++;
        }
    }
}

/* Move particle i for the whole step, from the world's state into the stepper's next state. */
static void move_one(sim_stepper *s, sim_world *w, int32_t i)
{
    const sim_real lo = w->lo, hi = w->hi;
    sim_real x = w->x[i], y = w->y[i], vx = w->vx[i], vy = w->vy[i];
    const int32_t e = s->event[i];
    if (e == SIM_EVENT_NONE) {
        x += vx;
        y += vy;
    } else if (e == SIM_WALL) {
        const sim_real t = s->event_t[i];
        const sim_real tx = axis_time(x, vx, lo, hi), ty = axis_time(y, vy, lo, hi);
        x += t * vx;
        y += t * vy;
        if (tx == t) {
            x = axis_wall(vx, lo, hi);
            vx = -vx;
        }
        if (ty == t) {
            y = axis_wall(vy, lo, hi);
            vy = -vy;
        }
        w->wcoll[i]++;
        finish(&x, &y, vx, vy, 1 - t, lo, hi);
    } else {
        /* Both partners evaluate the same expressions on the same old state, in the pair's
         * (lower, higher) order, so each computes bit-identical n, ua and ub on its own. */
        const sim_real t = s->event_t[i];
        const int32_t a = i < e ? i : e, b = i < e ? e : i;
        const sim_real xa = w->x[a] + t * w->vx[a], ya = w->y[a] + t * w->vy[a];
        const sim_real xb = w->x[b] + t * w->vx[b], yb = w->y[b] + t * w->vy[b];
        const sim_real dx = xb - xa, dy = yb - ya;
        const sim_real dist = SIM_SQRT(dx * dx + dy * dy);
        x += t * vx;
        y += t * vy;
        /* dist is about 2r > 0 at contact; it is 0 only if 2r underflows, and then no normal
         * exists: the discs keep their velocities. */
        if (dist > 0) {
            const sim_real nx = dx / dist, ny = dy / dist;
            const sim_real ua = w->vx[a] * nx + w->vy[a] * ny;
            const sim_real ub = w->vx[b] * nx + w->vy[b] * ny;
            const sim_real du = i == a ? ub - ua : ua - ub;
            vx = vx + du * nx;
            vy = vy + du * ny;
        }
        w->pcoll[i]++;
        finish(&x, &y, vx, vy, 1 - t, lo, hi);
    }
    s->nx[i] = clamp(x, lo, hi);
    s->ny[i] = clamp(y, lo, hi);
    s->nvx[i] = vx;
    s->nvy[i] = vy;
}

static void swap_arrays(sim_real **a, sim_real **b)
{
    sim_real *t = *a;
    *a = *b;
    *b = t;
}

int sim_step(sim_stepper *s, sim_world *w, sim_stats *stats)
{
    const int32_t n = w->n;
    double t0 = omp_get_wtime(), t1;
    if (!s->walls_ready) {
        find_walls(s, w);
        t1 = omp_get_wtime();
        stats->walls_s += t1 - t0;
        t0 = t1;
    }
    s->walls_ready = false;
    s->variant->find_pairs(w, &s->sink);
    t1 = omp_get_wtime();
    stats->broad_s += t1 - t0;
    const size_t count = merge_candidates(s, stats);
    if (count == (size_t)-1)
        return -1;
    t0 = omp_get_wtime();
    stats->sort_s += t0 - t1;
    resolve(s, n, count, stats);
    t1 = omp_get_wtime();
    stats->resolve_s += t1 - t0;
    /* Motion, then the next step's wall candidates from the new state, in one parallel region:
     * two `omp for schedule(static) nowait` loops over the same range give each thread the
     * same particles in both (OpenMP's rule for static loops of equal length in one region),
     * so a thread reads only new states it wrote itself and needs no barrier between them.
     * The phases are timed on thread 0, the thread that calls sim_step: motion_s from the
     * region's start to its motion loop's end, walls_s its wall loop; the region's start-up
     * before thread 0 runs and the closing barrier (waiting for the other threads) are in
     * neither, but in sim_s. Every particle costs about the same here, so a static schedule
     * balances. */
    clear_walls(s);
    double motion_s = 0, walls_s = 0;
#pragma omp parallel num_threads(s->threads) if (s->parallel && n >= SIM_PARALLEL_MIN)
    {
        const int me = omp_get_thread_num();
        sim_cand_buf *buf = &s->walls[me];
        const double m0 = me == 0 ? omp_get_wtime() : 0;
#pragma omp for schedule(static) nowait
        for (int32_t i = 0; i < n; i++)
            move_one(s, w, i);
        const double m1 = me == 0 ? omp_get_wtime() : 0;
#pragma omp for schedule(static) nowait
        for (int32_t i = 0; i < n; i++)
            push_wall(buf, s->nx[i], s->ny[i], s->nvx[i], s->nvy[i], w->lo, w->hi, i);
        if (me == 0) {
            motion_s = m1 - m0;
            walls_s = omp_get_wtime() - m1;
        }
    }
    stats->motion_s += motion_s;
    stats->walls_s += walls_s;
    swap_arrays(&w->x, &s->nx);
    swap_arrays(&w->y, &s->ny);
    swap_arrays(&w->vx, &s->nvx);
    swap_arrays(&w->vy, &s->nvy);
    s->walls_ready = true;
    return 0;
}
