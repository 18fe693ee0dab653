/*
 * grid_prefilter.c: what happens to a pair once the float prefilter (run_prefilter, grid.h) has
 * passed it: above GRID_SMALL_N it waits in a queue while its particles' double state is
 * prefetched; pair_found then decides in double (near_pair, then the shared kernel
 * sim_pair_time) and pushes the candidate from exactly one slice.
 */
#include "grid.h"

/* A pair near in slice cx->k (particles a, b): test it, and push it from its one slice. */
static void pair_found(const grid_ctx *cx, int32_t a, int32_t b)
{
    const int32_t i = a < b ? a : b, j = a < b ? b : a;
    const double *tk = cx->s->tk, reach2 = cx->g->reach2;
    const int k = cx->k, K = cx->g->K;
    /* The decision for this slice, in the (i, j) order every slice uses. */
    if (!near_pair(cx->w, tk, reach2, i, j, k))
        return;
    sim_real t;
    if (!sim_pair_time(cx->w, i, j, &t))
        return;
    int kt = (int)((double)t * K);
    if (kt > K - 1)
        kt = K - 1;
    if (kt != k) {
        if (near_pair(cx->w, tk, reach2, i, j, kt))
            return; /* slice kt pushes it */
        for (int e = 0; e < k; e++)
            if (near_pair(cx->w, tk, reach2, i, j, e))
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
    prefetch_line(&w->x[i]), prefetch_line(&w->y[i]);
    prefetch_line(&w->vx[i]), prefetch_line(&w->vy[i]);
}

void grid_pair_passed(const grid_ctx *cx, int32_t a, int32_t b)
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

void grid_queue_flush(const grid_ctx *cx)
{
    grid_queue *q = cx->queue;
    const int first = (q->at + GRID_QUEUE - q->len) % GRID_QUEUE;
    for (int m = 0; m < q->len; m++)
        pair_found(cx, q->a[(first + m) % GRID_QUEUE], q->b[(first + m) % GRID_QUEUE]);
    q->at = q->len = 0;
}
