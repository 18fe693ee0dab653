/*
 * grid_state.c: the grid finder's per-run and per-thread state, allocated once per run by
 * grid_scratch_create (O(N) per thread), and freed.
 */
#include <stdlib.h>

#include "grid.h"

static void thread_free(grid_thread *t)
{
    for (int b = 0; b < 2; b++) {
        free(t->set[b].bx), free(t->set[b].by), free(t->set[b].ux), free(t->set[b].uy);
        free(t->set[b].px), free(t->set[b].py);
        free(t->set[b].id), free(t->wide[b]);
    }
    free(t->cx0), free(t->cy0), free(t->flag), free(t->scell), free(t->sext), free(t->pos);
    free(t->ent), free(t->tmp), free(t->skey), free(t->hist);
}

void grid_scratch_destroy(void *p)
{
    grid_scratch *s = p;
    if (!s)
        return;
    if (s->th)
        for (int k = 0; k < s->threads; k++)
            thread_free(&s->th[k]);
    free(s->th);
    free(s->bx), free(s->by), free(s->ux), free(s->uy), free(s->part), free(s->tk);
    free(s->ord), free(s->ord_next);
    free(s);
}

static int thread_alloc(grid_thread *t, size_t n)
{
    const size_t i = n * sizeof(int32_t), u = n * sizeof(uint64_t), f = n + GRID_LANES;
    int ok = 1;
    for (int b = 0; b < 2; b++) {
        grid_set *z = &t->set[b];
        /* Zeroed: the lanes read past the last entry are always finite. */
        z->bx = calloc(f, sizeof(float)), z->by = calloc(f, sizeof(float));
        z->ux = calloc(f, sizeof(float)), z->uy = calloc(f, sizeof(float));
        z->px = calloc(f, sizeof(float)), z->py = calloc(f, sizeof(float));
        z->id = calloc(f, sizeof(int32_t)), t->wide[b] = malloc(i);
        ok &= z->bx && z->by && z->ux && z->uy && z->px && z->py && z->id && t->wide[b];
    }
    /* The last slot, n + GRID_LANES - 1 = N + GRID_LANES: a slice has at most N entries, and
     * the prefilter reads at most GRID_LANES - 1 slots past the last. */
    t->sink = (int32_t)(f - 1);
    t->cx0 = malloc(i), t->cy0 = malloc(i), t->flag = malloc(i), t->scell = malloc(i);
    t->sext = malloc(n);
    t->pos_cap = GRID_DENSE_CELLS_PER_PARTICLE * (uint64_t)n + GRID_DENSE_CELLS_MIN;
    t->pos = malloc((size_t)(t->pos_cap + 2) * sizeof(int32_t));
    t->ent = malloc(u), t->tmp = malloc(u), t->skey = malloc(u);
    t->hist = malloc(((size_t)1 << GRID_RADIX_MAX_BITS) * sizeof(uint32_t));
    ok &= t->cx0 && t->cy0 && t->flag && t->scell && t->sext && t->pos && t->ent && t->tmp &&
          t->skey && t->hist;
    return ok ? 0 : -1;
}

void *grid_scratch_create(const sim_world *w, int threads)
{
    grid_scratch *s = calloc(1, sizeof *s);
    if (!s)
        return NULL;
    const size_t n = (size_t)w->n + 1;
    s->n = w->n;
    s->threads = threads;
    s->bx = malloc(n * sizeof(float)), s->by = malloc(n * sizeof(float));
    s->ux = malloc(n * sizeof(float)), s->uy = malloc(n * sizeof(float));
    s->part = malloc(n * sizeof *s->part);
    s->ord = malloc(n * sizeof(int32_t)), s->ord_next = malloc(n * sizeof(int32_t));
    s->tk = malloc((GRID_K_MAX + 1) * sizeof(double));
    s->th = calloc((size_t)threads, sizeof *s->th);
    if (!s->bx || !s->by || !s->ux || !s->uy || !s->part || !s->ord || !s->ord_next || !s->tk ||
        !s->th) {
        grid_scratch_destroy(s);
        return NULL;
    }
    for (int32_t i = 0; i < w->n; i++)
        s->ord[i] = i;
    for (int k = 0; k < threads; k++)
        if (thread_alloc(&s->th[k], n)) {
            grid_scratch_destroy(s);
            return NULL;
        }
    return s;
}
