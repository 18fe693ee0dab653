/*
 * sim_resolve.c: SPEC §2's resolution, the one greedy walk that decides which candidates of a
 * step are accepted.
 */
#include <stddef.h>

#include "sim_stepper.h"

/* SPEC §2's greedy walk over all candidates in key order (t; pair before wall; i; j), accepting
 * a candidate when neither of its particles is taken yet, done without sorting the walls:
 *  1. the pairs, in key order: particle a is taken when an accepted pair took it, or when its
 *     wall candidate comes first (wall_t[a] < t: at equal times the pair comes first). That
 *     wall was accepted then, unless a pair took a before it, and then a is taken anyway; a
 *     wall time above 1 (no candidate) never comes first. Such a pair is refused and changes
 *     nothing, so the sort dropped it already (sim_sort.c): here a pair is accepted when
 *     no accepted pair took either particle;
 *  2. the walls, in particle order: a wall is accepted when no accepted pair took its particle
 *     (a pair after the wall that takes its particle would have been refused in 1).
 * Branch-free (what is accepted, and which particles are free, is random: branches on it
 * mispredicted): every candidate is written to its list of accepted moves, which advances only
 * past accepted ones. The flags are counted and cleared by the motion's pass over every
 * particle (sim_step.c's move_free). */
void sim_resolve(sim_stepper *s, size_t count, sim_stats *stats)
{
    unsigned char *restrict taken = s->taken;
    const sim_cand *restrict cand = s->merged;
    sim_cand *restrict pairs = s->pair_moves, *restrict walls = s->wall_moves;
    size_t np = 0, nw = 0;
    for (size_t k = 0; k < count; k++) {
        const sim_cand c = cand[k];
        const unsigned ok = !(taken[c.i] | taken[c.j]);
        taken[c.i] |= (unsigned char)(ok * SIM_TAKEN_PAIR);
        taken[c.j] |= (unsigned char)(ok * SIM_TAKEN_PAIR);
        pairs[np] = c;
        np += ok;
    }
    for (int b = 0; b < s->threads; b++) {
        const sim_cand *restrict wall = s->walls[b].items;
        for (size_t k = 0; k < s->walls[b].len; k++) {
            const sim_cand c = wall[k];
            const unsigned ok = !taken[c.i];
            taken[c.i] |= (unsigned char)(ok * SIM_TAKEN_WALL);
            walls[nw] = c;
            nw += ok;
        }
    }
    s->wall_moves_len = nw;
    s->pair_moves_len = np;
    stats->wall_collisions += nw;
    stats->pair_collisions += np;
}
