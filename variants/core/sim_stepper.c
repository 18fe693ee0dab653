/*
 * sim_stepper.c: the stepper's life: its memory (sized for the world and the thread count
 * once, grown only where a step needs more candidates than any before), the collision counts
 * it keeps between flushes, and the per-writer work --timing reports.
 */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "sim_stepper.h"

bool sim_cand_reserve(sim_cand **items, size_t *cap, size_t need)
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
    s->taken = calloc(n + 1, 1);
    s->wall_t = malloc((n + 1) * sizeof *s->wall_t);
    s->pair_count = calloc(n + 1, 1);
    s->wall_count = calloc(n + 1, 1);
    s->pcoll = w->pcoll;
    s->wcoll = w->wcoll;
    s->n = w->n;
    s->nx = malloc(n * sizeof(sim_real) + 1);
    s->ny = malloc(n * sizeof(sim_real) + 1);
    s->writer_pairs = calloc((size_t)count, sizeof *s->writer_pairs);
    s->sources = malloc((size_t)count * sizeof *s->sources);
    s->source_len = malloc((size_t)count * sizeof *s->source_len);
    if (!s->sink.bufs || !s->walls || !s->taken || !s->wall_t || !s->pair_count ||
        !s->wall_count || !s->nx || !s->ny ||
        !s->writer_pairs || !s->sources || !s->source_len) {
        sim_stepper_destroy(s);
        return NULL;
    }
    memset(s->sink.bufs, 0, (size_t)count * sizeof(sim_cand_buf));
    s->sink.wall_t = s->wall_t;
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

void sim_flush_counts(sim_stepper *s)
{
    if (!s->pair_count || !s->wall_count)
        return;
    for (int32_t i = 0; i < s->n; i++) {
        s->pcoll[i] += s->pair_count[i];
        s->wcoll[i] += s->wall_count[i];
        s->pair_count[i] = s->wall_count[i] = 0;
    }
    s->unflushed = 0;
}

void sim_stepper_destroy(sim_stepper *s)
{
    if (!s)
        return;
    sim_flush_counts(s);
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
    free(s->hist);
    free(s->sources);
    free(s->source_len);
    free(s->wall_moves);
    free(s->pair_out);
    free(s->pair_moves);
    free(s->chunk_state);
    free(s->chunk_mask);
    free(s->taken);
    free(s->wall_t);
    free(s->pair_count);
    free(s->wall_count);
    free(s->nx);
    free(s->ny);
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
