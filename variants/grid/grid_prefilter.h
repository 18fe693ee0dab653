/*
 * grid_prefilter.h: what happens to a pair once the binning has put it in front of the finder.
 * run_prefilter tests a probe against runs of entries in float, GRID_LANES pairs a vector
 * (near_f32); every pair it passes goes to pair_found, which decides in double (near_pair,
 * then the shared kernel sim_pair_time) and pushes the candidate from exactly one slice.
 */
#ifndef GRID_PREFILTER_H
#define GRID_PREFILTER_H

#include <string.h>
#if defined(__AVX__)
#include <immintrin.h>
#endif

#include "grid_geometry.h"

/* Pairs the prefilter passed wait in a ring of GRID_QUEUE while their particles' double state
 * (s->part) and the kernel's inputs (the world's arrays) are prefetched: at N = 10^6 these are
 * reads anywhere in 32 MB + 32 MB, and pair_found, which took each miss in turn, was 22% of the
 * finder's samples (perf, one thread, `1000000 200000 1 2`). */
#define GRID_QUEUE 16
typedef struct grid_queue {
    int32_t a[GRID_QUEUE], b[GRID_QUEUE];
    /* The len <= GRID_QUEUE waiting pairs end at slot at - 1 (mod GRID_QUEUE). No count of
     * all the pairs a slice passed: on one slice of N >= 92,682 particles (f32_off scenes) a
     * 32-bit one could wrap, and the pairs queued then were lost. */
    int at, len;
    int on;     /* N > GRID_SMALL_N: where the state is in cache (the report benchmark) the
                 * queue cost 6% of the finder's time (median ratio of 15 interleaved runs) */
} grid_queue;

/* What the finder knows while it looks at the pairs of slice k. */
typedef struct grid_ctx {
    const sim_world *w;
    const grid_scratch *s;
    const grid_plan *g;
    int k;
    sim_cand_buf *buf;
    int32_t *ord_next; /* the step's last slice: where the new cell order goes */
    grid_queue *queue; /* pairs passed by the prefilter, not yet decided */
} grid_ctx;

/* A pair near in slice cx->k (particles a, b): test it, and push it from its one slice. */
static void pair_found(const grid_ctx *cx, int32_t a, int32_t b)
{
    const int32_t i = a < b ? a : b, j = a < b ? b : a;
    const grid_particle *part = cx->s->part;
    const double *tk = cx->s->tk, reach2 = cx->g->reach2;
    const int k = cx->k, K = cx->g->K;
    /* The decision for this slice, in the (i, j) order every slice uses. */
    if (!near_pair(part, tk, reach2, i, j, k))
        return;
    sim_real t;
    if (!sim_pair_time(cx->w, i, j, &t))
        return;
    int kt = (int)((double)t * K);
    if (kt > K - 1)
        kt = K - 1;
    if (kt != k) {
        if (near_pair(part, tk, reach2, i, j, kt))
            return; /* slice kt pushes it */
        for (int e = 0; e < k; e++)
            if (near_pair(part, tk, reach2, i, j, e))
                return; /* an earlier slice pushes it */
    }
    sim_cand_push(cx->buf, t, i, j);
}

/* Start loading the cache line at p. gcc 12 at -O1 and above dropped every __builtin_prefetch
 * of this file (seen in the assembly), so on x86 the instruction is written out. */
static inline void prefetch_line(const void *p)
{
#if defined(__x86_64__) || defined(__i386__)
    __asm__ volatile("prefetcht0 %0" : : "m"(*(const char *)p));
#else
    __builtin_prefetch(p);
#endif
}

/* Particle i's reads in pair_found and sim_pair_time, started now. */
static inline void prefetch_particle(const grid_ctx *cx, int32_t i)
{
    const sim_world *w = cx->w;
    prefetch_line(&cx->s->part[i]);
    prefetch_line(&w->x[i]), prefetch_line(&w->y[i]);
    prefetch_line(&w->vx[i]), prefetch_line(&w->vy[i]);
}

/* Pair (a, b) passed the prefilter: queue it, and decide the one queued GRID_QUEUE pairs ago.
 * The decisions and pushes of a slice are those of deciding at once, in the same order. */
__attribute__((noinline)) /* inlined, it slowed the prefilter's loop at N = 10^4 by 12% */
static void pair_passed(const grid_ctx *cx, int32_t a, int32_t b)
{
    grid_queue *q = cx->queue;
    if (!q->on) {
        pair_found(cx, a, b);
        return;
    }
    const int slot = q->at;
    if (q->len == GRID_QUEUE)
        pair_found(cx, q->a[slot], q->b[slot]); /* the oldest waiting pair */
    else
        q->len++;
    prefetch_particle(cx, a), prefetch_particle(cx, b);
    q->a[slot] = a, q->b[slot] = b;
    q->at = (slot + 1) % GRID_QUEUE;
}

/* Decide every pair still queued (at the end of a slice). */
static void queue_flush(const grid_ctx *cx)
{
    grid_queue *q = cx->queue;
    const int first = (q->at + GRID_QUEUE - q->len) % GRID_QUEUE;
    for (int m = 0; m < q->len; m++)
        pair_found(cx, q->a[(first + m) % GRID_QUEUE], q->b[(first + m) % GRID_QUEUE]);
    q->at = q->len = 0;
}

/* One particle looked at against runs of entries: its prefilter floats and its id. */
typedef struct grid_probe {
    float x, y, wx, wy;
    int32_t id;
} grid_probe;

/* The prefilter on the chunk of entries [b, b + GRID_LANES) of z against probe a. */
static inline grid_vi chunk_near(const grid_set *z, int32_t b, const grid_probe *a, float r2,
                                 float tend)
{
    grid_vf X, Y, WX, WY;
    memcpy(&X, z->px + b, sizeof X), memcpy(&Y, z->py + b, sizeof Y);
    memcpy(&WX, z->ux + b, sizeof WX), memcpy(&WY, z->uy + b, sizeof WY);
    return near_f32(X - a->x, Y - a->y, WX - a->wx, WY - a->wy, r2, tend);
}

/* Is any lane set? One vptest (AVX) or vptestmd (AVX-512): a lane-by-lane OR became a chain of lane
 * extractions after every run, several percent of the finder's time. */
static inline int vi_any(grid_vi v)
{
#if GRID_LANES == 16
    return _mm512_test_epi32_mask((__m512i)v, (__m512i)v) != 0;
#elif defined(__AVX__) && GRID_LANES == 8
    return !_mm256_testz_si256((__m256i)v, (__m256i)v);
#else
    int32_t r = 0;
    for (int l = 0; l < GRID_LANES; l++)
        r |= v[l];
    return r != 0;
#endif
}

/* Where chunk c of two runs begins: the n1 chunks of the run at lo1, then those at lo2. */
static inline int32_t chunk_start(int32_t c, int32_t n1, int32_t lo1, int32_t lo2)
{
    return c < n1 ? lo1 + c * GRID_LANES : lo2 + (c - n1) * GRID_LANES;
}

/* The prefilter over two runs of entries of z, [lo1, hi1) and [lo2, hi2) (either may be
 * empty), against probe a: every pair it passes goes to pair_found, which decides. One loop
 * over the chunks of both (measured as fast as two loops; one place for the bookkeeping). Reads
 * up to GRID_LANES - 1 entries past a run's end. Returns the pairs looked at. */
static inline int32_t run_prefilter(const grid_ctx *cx, const grid_set *z, int32_t lo1,
                                    int32_t hi1, int32_t lo2, int32_t hi2, const grid_probe *a)
{
    const float r2 = cx->g->freach2, tend = cx->g->fend;
    const int32_t len1 = hi1 > lo1 ? hi1 - lo1 : 0, len2 = hi2 > lo2 ? hi2 - lo2 : 0;
    const int32_t n1 = (len1 + GRID_LANES - 1) / GRID_LANES;
    const int32_t n = n1 + (len2 + GRID_LANES - 1) / GRID_LANES;
    grid_vi any = {0};
    /* Lanes past a run's end are not masked here: they are entries of the slice or the zeroed
     * padding, and at worst make a run fire; the second pass masks them. */
    for (int32_t c = 0; c < n; c++)
        any |= chunk_near(z, chunk_start(c, n1, lo1, lo2), a, r2, tend);
    if (vi_any(any))
        for (int32_t c = 0; c < n; c++) {
            const int32_t b = chunk_start(c, n1, lo1, lo2);
            const grid_vi lane = GRID_LANE_IDS;
            const grid_vi hit = chunk_near(z, b, a, r2, tend) & (lane < (c < n1 ? hi1 : hi2) - b);
            for (int l = 0; l < GRID_LANES; l++)
                if (hit[l])
                    pair_passed(cx, a->id, z->id[b + l]);
        }
    return len1 + len2;
}

#endif /* GRID_PREFILTER_H */
