/*
 * grid_prefilter.h: what happens to a pair once the binning has put it in front of the finder.
 * run_prefilter tests a probe against runs of entries in float, GRID_LANES pairs a vector
 * (near_f32_line, then near_f32; their lanes come back as bits); every pair they pass goes to
 * pair_found, which decides in double (near_pair, then the shared kernel sim_pair_time) and
 * pushes the candidate from exactly one slice.
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

/* The chunk of entries [b, b + GRID_LANES) of z against probe a: relative position and
 * displacement, lane by lane. */
typedef struct grid_chunk {
    grid_vf px, py, wx, wy;
} grid_chunk;

static inline grid_chunk chunk_of(const grid_set *z, int32_t b, const grid_probe *a)
{
    grid_vf X, Y, WX, WY;
    memcpy(&X, z->px + b, sizeof X), memcpy(&Y, z->py + b, sizeof Y);
    memcpy(&WX, z->ux + b, sizeof WX), memcpy(&WY, z->uy + b, sizeof WY);
    return (grid_chunk){X - a->x, Y - a->y, WX - a->wx, WY - a->wy};
}

/* The prefilter over the run [lo, hi) of z against probe a: every pair it passes goes to
 * pair_passed, in entry order. Reads up to GRID_LANES - 1 entries past the run's end. One
 * pass, a branch a chunk that is rarely taken: the lanes are a mask, the chunk's passed pairs
 * its set bits, near_f32_line on every chunk and near_f32 on those where a lane passed it
 * (grid_geometry.h). The single pass took 0.91x the finder's time of two, an OR of every
 * chunk's lanes as a vector and the chunks again where any was set (report benchmark, one
 * thread, medians of 9 interleaved runs); keeping the lanes in mask registers to the end
 * 0.96x more. The rare path out of line took 1.08x (a noinline function: gcc then kept the
 * run's pointers and the chunk in memory) and 1.3x (an inner loop without the call, left at
 * the first lane passed). */
static inline void scan_run(const grid_ctx *cx, const grid_set *z, int32_t lo, int32_t hi,
                            const grid_probe *a, float r2, float tend)
{
    /* A local copy: pair_passed's stores could change *z, which made gcc reload its pointers
     * on every chunk. */
    const grid_set zl = *z;
    for (int32_t b = lo; b < hi; b += GRID_LANES) {
        const grid_chunk q = chunk_of(&zl, b, a);
        uint32_t hit = near_f32_line(q.px, q.py, q.wx, q.wy, r2, tend);
        if (__builtin_expect(hit != 0, 0)) {
            hit &= near_f32(q.px, q.py, q.wx, q.wy, r2, tend);
            /* Lanes past the run's end: entries of the slice or the zeroed padding. */
            if (hi - b < GRID_LANES)
                hit &= (1u << (hi - b)) - 1;
            for (; hit; hit &= hit - 1)
                pair_passed(cx, a->id, zl.id[b + __builtin_ctz(hit)]);
        }
    }
}

/* The prefilter over two runs of entries of z, [lo1, hi1) and [lo2, hi2) (either may be
 * empty), against probe a. Returns the pairs looked at. */
static inline int32_t run_prefilter(const grid_ctx *cx, const grid_set *z, int32_t lo1,
                                    int32_t hi1, int32_t lo2, int32_t hi2, const grid_probe *a)
{
    const float r2 = cx->g->freach2, tend = cx->g->fend;
    scan_run(cx, z, lo1, hi1, a, r2, tend);
    scan_run(cx, z, lo2, hi2, a, r2, tend);
    return (hi1 > lo1 ? hi1 - lo1 : 0) + (hi2 > lo2 ? hi2 - lo2 : 0);
}

#endif /* GRID_PREFILTER_H */
