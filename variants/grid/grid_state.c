/*
 * grid_state.c: the grid finder's per-run state: what the whole team shares, O(N) once, and
 * each thread's scratch, sized for the items of its bands and grown on demand, so that the
 * memory does not grow with the thread count (a thread bins about N / T items a slice).
 */
#include <stdlib.h>

#include "grid.h"

/* p grown to n elements of `size` bytes (untouched, so not resident, beyond what is written);
 * p itself, and *bad set, when memory is short. */
static void *grow(void *p, size_t n, size_t size, int *bad)
{
    void *q = realloc(p, n * size);
    if (!q) {
        *bad = 1;
        return p;
    }
    return q;
}

static void thread_free(grid_thread *t)
{
    for (int b = 0; b < 2; b++) {
        free(t->set[b].bx), free(t->set[b].by), free(t->set[b].ux), free(t->set[b].uy);
        free(t->set[b].px), free(t->set[b].py);
        free(t->set[b].id), free(t->wide[b]);
    }
    free(t->cx0), free(t->cy0), free(t->flag), free(t->scell), free(t->sext), free(t->pos);
    free(t->ent), free(t->tmp), free(t->skey), free(t->hist);
    free(t->prow), free(t->pband), free(t->bound), free(t->cur), free(t->sample);
}

int grid_thread_reserve(grid_thread *t, int32_t items, int sets)
{
    if (items <= t->cap && sets <= t->sets)
        return 0;
    /* A quarter more than asked: a band's items change a little from slice to slice. */
    const int64_t want = items > t->cap ? (int64_t)items + items / 4 + GRID_LANES : t->cap;
    if (want > INT32_MAX - 2 * GRID_LANES)
        return -1;
    const size_t c = (size_t)want, f = c + GRID_LANES + 1;
    int bad = 0;
    for (int b = 0; b < sets; b++) {
        grid_set *z = &t->set[b];
        z->bx = grow(z->bx, f, sizeof(float), &bad);
        z->by = grow(z->by, f, sizeof(float), &bad);
        z->ux = grow(z->ux, f, sizeof(float), &bad);
        z->uy = grow(z->uy, f, sizeof(float), &bad);
        z->px = grow(z->px, f, sizeof(float), &bad);
        z->py = grow(z->py, f, sizeof(float), &bad);
        z->id = grow(z->id, f, sizeof(int32_t), &bad);
        t->wide[b] = grow(t->wide[b], c, sizeof(int32_t), &bad);
    }
    t->cx0 = grow(t->cx0, c, sizeof(int32_t), &bad);
    t->cy0 = grow(t->cy0, c, sizeof(int32_t), &bad);
    t->flag = grow(t->flag, c, sizeof(int32_t), &bad);
    t->scell = grow(t->scell, c, sizeof(int32_t), &bad);
    t->sext = grow(t->sext, c, 1, &bad);
    t->ent = grow(t->ent, c, sizeof(uint64_t), &bad);
    t->tmp = grow(t->tmp, c, sizeof(uint64_t), &bad);
    t->skey = grow(t->skey, c, sizeof(uint64_t), &bad);
    if (!t->hist)
        t->hist = grow(t->hist, (size_t)1 << GRID_RADIX_MAX_BITS, sizeof(uint32_t), &bad);
    if (bad)
        return -1; /* what did grow is freed with the scratch */
    t->cap = (int32_t)c;
    t->sets = sets > t->sets ? sets : t->sets;
    /* The last slot: the prefilter reads at most GRID_LANES - 1 slots past an entry. */
    t->sink = (int32_t)(f - 1);
    return 0;
}

int grid_thread_reserve_part(grid_thread *t, int32_t part)
{
    if (part <= t->pcap)
        return 0;
    const size_t c = (size_t)part + (size_t)part / 4 + 1;
    int bad = 0;
    t->prow = grow(t->prow, c, sizeof(int32_t), &bad);
    t->pband = grow(t->pband, c, sizeof(int32_t), &bad);
    if (bad)
        return -1;
    t->pcap = (int32_t)c;
    return 0;
}

int grid_thread_reserve_keys(grid_thread *t, uint64_t keys)
{
    if (keys <= t->pos_cap)
        return 0;
    const uint64_t c = keys + keys / 4;
    int bad = 0;
    t->pos = grow(t->pos, (size_t)c + 2, sizeof(int32_t), &bad);
    if (bad)
        return -1;
    t->pos_cap = c;
    return 0;
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
    free(s->bx), free(s->by), free(s->ux), free(s->uy), free(s->tk);
    free(s->ord), free(s->ord_next);
    free(s->team.bx), free(s->team.by), free(s->team.ux), free(s->team.uy), free(s->team.id);
    free(s->team.wide), free(s->team.count), free(s->team.extent), free(s->team.speeds);
    for (int b = 0; b < 2; b++)
        free(s->team.whole_key[b]), free(s->team.whole_flag[b]);
    free(s->team.share);
    free(s);
}

void *grid_scratch_create(const sim_world *w, int threads)
{
    grid_scratch *s = calloc(1, sizeof *s);
    if (!s)
        return NULL;
    const size_t n = (size_t)w->n + 1;
    s->n = w->n;
    s->direct_n = GRID_DIRECT_N;
    s->slice_parts = 1;
    s->threads = threads;
    s->bx = malloc(n * sizeof(float)), s->by = malloc(n * sizeof(float));
    s->ux = malloc(n * sizeof(float)), s->uy = malloc(n * sizeof(float));
    s->ord = malloc(n * sizeof(int32_t)), s->ord_next = malloc(n * sizeof(int32_t));
    s->tk = malloc((GRID_K_MAX + 1) * sizeof(double));
    s->th = calloc((size_t)threads, sizeof *s->th);
    int bad = !s->bx || !s->by || !s->ux || !s->uy || !s->ord || !s->ord_next ||
              !s->tk || !s->th;
    if (!bad && threads > 1) {
        /* A band's items are its base entries and the upper neighbours of the band below: an
         * item is in at most GRID_SUB_MAX + 1 bands. Only what a slice writes is resident; with
         * bands many rows high that is about N. */
        const size_t p = (GRID_SUB_MAX + 1) * n;
        grid_team *t = &s->team;
        t->bx = malloc(p * sizeof(float)), t->by = malloc(p * sizeof(float));
        t->ux = malloc(p * sizeof(float)), t->uy = malloc(p * sizeof(float));
        t->id = malloc(p * sizeof(int32_t)), t->wide = malloc(n * sizeof(int32_t));
        t->count = malloc((size_t)threads * GRID_COUNT_STRIDE((size_t)threads) * sizeof(int32_t));
        t->extent = malloc((size_t)threads * sizeof *t->extent);
        t->speeds = malloc((size_t)threads * GRID_SPEED_BINS * sizeof *t->speeds);
        t->share = aligned_alloc(_Alignof(grid_band_share), (size_t)threads * sizeof *t->share);
        bad = !t->bx || !t->by || !t->ux || !t->uy || !t->id || !t->wide || !t->count ||
              !t->extent || !t->speeds || !t->share;
        for (int k = 0; k < threads && !bad; k++) {
            t->share[k].ready = 0;
            s->th[k].bound = malloc(((size_t)threads + 1) * sizeof(int32_t));
            s->th[k].cur = malloc((size_t)threads * sizeof(int32_t));
            s->th[k].sample = malloc((size_t)threads * GRID_BAND_SAMPLES * sizeof(int32_t));
            bad = !s->th[k].bound || !s->th[k].cur || !s->th[k].sample;
        }
    }
    if (!bad && threads >= GRID_PLAN_TEAM_MIN && w->n <= GRID_DIRECT_N) {
        /* grid_run_direct's keys of every slice. */
        grid_team *t = &s->team;
        for (int b = 0; b < 2; b++) {
            t->whole_key[b] = malloc(n * sizeof(int32_t));
            t->whole_flag[b] = malloc(n * sizeof(int32_t));
            bad = bad || !t->whole_key[b] || !t->whole_flag[b];
        }
    }
    if (bad) {
        grid_scratch_destroy(s);
        return NULL;
    }
    for (int32_t i = 0; i < w->n; i++)
        s->ord[i] = i;
    return s;
}
