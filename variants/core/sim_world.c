/*
 * sim_world.c: the world's memory. O(N): no N x N structure anywhere (the seed's N x N
 * collision matrix is why it could not run 50,000 particles).
 */
#include <stdlib.h>

#include "sim_core.h"

/* Rough upper bound of the candidates per particle the step keeps, for the memory estimate. */
#define SIM_CANDS_PER_PARTICLE_ESTIMATE 2

size_t sim_bytes_per_particle(void)
{
    /* world: x y vx vy + pcoll wcoll; stepper: next x y, wall_t, the walk's flag and two byte
     * counts; input bitmap; candidates, three times: the writers' lists, the sorted pairs and
     * the accepted moves. An estimate, for refusing an N up front: not counted are the sort's
     * histogram (half a word per candidate), the accepted pairs' new states on a team (64
     * bytes an accepted pair) and the variant's scratch (grid's float copies and bins);
     * a million particles peaked at 363 MiB (bench.py million), 380 bytes a particle. */
    return 7 * sizeof(sim_real) + 2 * sizeof(int64_t) + 3 + 1 +
           3 * SIM_CANDS_PER_PARTICLE_ESTIMATE * sizeof(sim_cand);
}

int sim_world_alloc(sim_world *w, const sim_header *h)
{
    *w = (sim_world){0};
    w->n = h->n;
    w->L = (sim_real)h->L;
    w->r = (sim_real)h->r;
    w->lo = w->r;
    w->hi = w->L - w->r;
    const sim_real diam = 2 * w->r;
    w->diam2 = diam * diam;
    /* +1 so that N = 0 still gets distinct non-NULL arrays. */
    const size_t n = (size_t)h->n + 1;
    w->x = malloc(n * sizeof(sim_real));
    w->y = malloc(n * sizeof(sim_real));
    w->vx = malloc(n * sizeof(sim_real));
    w->vy = malloc(n * sizeof(sim_real));
    w->pcoll = calloc(n, sizeof(int64_t));
    w->wcoll = calloc(n, sizeof(int64_t));
    if (!w->x || !w->y || !w->vx || !w->vy || !w->pcoll || !w->wcoll) {
        sim_world_free(w);
        return -1;
    }
    return 0;
}

void sim_world_free(sim_world *w)
{
    free(w->x);
    free(w->y);
    free(w->vx);
    free(w->vy);
    free(w->pcoll);
    free(w->wcoll);
    *w = (sim_world){0};
}
