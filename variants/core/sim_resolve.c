/*
 * sim_resolve.c: SPEC §2's resolution, the one greedy walk that decides which candidates of a
 * step are accepted, on one thread or on the team with the same result.
 */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include <omp.h>

#include "sim_stepper.h"

/* Pairs a chunk of the team's walk: the unit the filters claim and the walker checks. A
 * multiple of 64, so that a chunk's survivor mask is whole words. */
#define SIM_RESOLVE_CHUNK 4096
/* Candidates ahead whose particles' flags are prefetched: the flags are a byte a particle, read
 * at random (a megabyte at a million particles, past L2). */
#define SIM_TAKEN_AHEAD 32

/* A chunk of the team's walk: not yet touched, being filtered, filtered (its mask is
 * complete), walked as it is (any filter's mask of it is ignored). */
enum { CHUNK_OPEN, CHUNK_FILTERING, CHUNK_FILTERED, CHUNK_WALKED };

/* The flags of the team's walk are written by the walker while filters read them: relaxed
 * atomic accesses (plain moves on x86) make that race-free, and any value a filter sees is
 * safe (see resolve_team). */
static inline unsigned char flag_load(const unsigned char *p)
{
    return __atomic_load_n(p, __ATOMIC_RELAXED);
}

static inline void flag_store(unsigned char *p, unsigned char v)
{
    __atomic_store_n(p, v, __ATOMIC_RELAXED);
}

/* Hint that particle i's and j's flags are read soon. */
static inline void prefetch_flags(const unsigned char *taken, sim_cand c)
{
#if defined(__GNUC__)
    __builtin_prefetch(&taken[c.i]);
    __builtin_prefetch(&taken[c.j]);
#else
    (void)taken;
    (void)c;
#endif
}

/* One pair of the walk: accepted when neither particle is taken; written to pairs[np] either
 * way, and the count returned advances only past an accepted one. Branch-free (what is
 * accepted, and which particles are free, is random: branches on it mispredicted). */
static inline size_t walk_one(unsigned char *taken, sim_cand c, sim_cand *pairs, size_t np)
{
    const unsigned char fi = flag_load(&taken[c.i]), fj = flag_load(&taken[c.j]);
    const unsigned ok = !(fi | fj);
    flag_store(&taken[c.i], (unsigned char)(fi | ok * SIM_TAKEN_PAIR));
    flag_store(&taken[c.j], (unsigned char)(fj | ok * SIM_TAKEN_PAIR));
    pairs[np] = c;
    return np + ok;
}

/* The walk over cand[k0, k1); returns the accepted count, np before. */
static size_t walk_range(unsigned char *taken, const sim_cand *restrict cand, size_t k0,
                         size_t k1, sim_cand *restrict pairs, size_t np)
{
    for (size_t k = k0; k < k1; k++) {
        if (k + SIM_TAKEN_AHEAD < k1)
            prefetch_flags(taken, cand[k + SIM_TAKEN_AHEAD]);
        np = walk_one(taken, cand[k], pairs, np);
    }
    return np;
}

/* The walk over the pairs of chunk `chunk` whose bit in mask is set (a filter's survivors). */
static size_t walk_mask(unsigned char *taken, const sim_cand *restrict cand,
                        const uint64_t *restrict mask, size_t chunk, sim_cand *restrict pairs,
                        size_t np)
{
    const size_t w0 = chunk * (SIM_RESOLVE_CHUNK / 64);
    for (size_t w = w0; w < w0 + SIM_RESOLVE_CHUNK / 64; w++)
        for (uint64_t m = mask[w]; m; m &= m - 1)
            np = walk_one(taken, cand[64 * w + (size_t)__builtin_ctzll(m)], pairs, np);
    return np;
}

/* Chunk `chunk`'s survivors into mask: the pairs neither of whose particles a flag marks
 * taken as the filter reads them. Bits past the last pair stay clear. */
static void filter_chunk(const unsigned char *taken, const sim_cand *restrict cand,
                         uint64_t *restrict mask, size_t chunk, size_t count)
{
    const size_t k0 = chunk * SIM_RESOLVE_CHUNK;
    const size_t k1 = count - k0 < SIM_RESOLVE_CHUNK ? count : k0 + SIM_RESOLVE_CHUNK;
    memset(mask + k0 / 64, 0, SIM_RESOLVE_CHUNK / 8);
    for (size_t k = k0; k < k1; k++) {
        if (k + SIM_TAKEN_AHEAD < k1)
            prefetch_flags(taken, cand[k + SIM_TAKEN_AHEAD]);
        const sim_cand c = cand[k];
        const uint64_t both_free = !(flag_load(&taken[c.i]) | flag_load(&taken[c.j]));
        mask[k / 64] |= both_free << (k % 64);
    }
}

/* The walls of the stepper's buffers (particle order) that no accepted pair took the particle
 * of (sim_resolve says why), written to out in order, their particles flagged; returns how
 * many. Branch-free, as walk_one. The flags through the atomic accessors: on the team, a filter
 * that lags may still read them (resolve_team). */
static size_t walk_walls(const sim_stepper *s, unsigned char *taken,
                         sim_cand *restrict out)
{
    size_t nw = 0;
    for (int b = 0; b < s->threads; b++) {
        const sim_cand *restrict wall = s->walls[b].items;
        for (size_t k = 0; k < s->walls[b].len; k++) {
            const sim_cand c = wall[k];
            const unsigned char f = flag_load(&taken[c.i]);
            const unsigned ok = !f;
            flag_store(&taken[c.i], (unsigned char)(f | ok * SIM_TAKEN_WALL));
            out[nw] = c;
            nw += ok;
        }
    }
    return nw;
}

/* Room for the team walk's states and survivor masks of `chunks` chunks. Returns 0, or -1
 * when memory ran out. */
static int reserve_chunks(sim_stepper *s, size_t chunks)
{
    if (chunks <= s->chunk_cap)
        return 0;
    int *state = realloc(s->chunk_state, chunks * sizeof *state);
    if (!state)
        return -1;
    s->chunk_state = state;
    uint64_t *mask = realloc(s->chunk_mask, chunks * (SIM_RESOLVE_CHUNK / 8));
    if (!mask)
        return -1;
    s->chunk_mask = mask;
    s->chunk_cap = chunks;
    return 0;
}

/* The walk on the team, with the serial walk's result, in one region and no barrier but its
 * end (on a loaded machine a barrier can wait a scheduler tick for a descheduled thread):
 *  1. the pairs: thread 0, the walker, walks the chunks in order; the others, the filters,
 *     claim chunks ahead of it and mark in a mask the pairs neither of whose particles is taken
 *     yet. A flag the walker has set belongs to a pair before the filtered chunk (a filter
 *     claims only a chunk the walker has not reached, and the walker uses its mask only if the
 *     filter finished before it got there), so a pair the filter drops would be refused by the
 *     walk: the walker walks a filtered chunk's survivors only, in order, and an unfiltered
 *     chunk whole. It never waits for a filter; a filter that lags only costs its own time.
 *     Every pair's fate is the walk's, whoever saw the chunk first: the result does not depend
 *     on timing. After the first chunks most pairs have lost a particle to an earlier pair and
 *     do not survive (docs/grid_bound.md has the share), and filtering, which only reads,
 *     costs less than walking;
 *  2. the walls, by the walker once it has walked the pairs: one pass in particle order, a
 *     fraction of the pairs' time (docs/grid_bound.md).
 * Returns 0, or -1 when memory ran out. */
static int resolve_team(sim_stepper *s, size_t count, size_t *np_out, size_t *nw_out)
{
    const size_t chunks = (count + SIM_RESOLVE_CHUNK - 1) / SIM_RESOLVE_CHUNK;
    if (reserve_chunks(s, chunks))
        return -1;
    for (size_t c = 0; c < chunks; c++)
        s->chunk_state[c] = CHUNK_OPEN;
    unsigned char *taken = s->taken;
    const sim_cand *cand = s->merged;
    uint64_t *mask = s->chunk_mask;
    int *state = s->chunk_state;
    size_t next = 1, np = 0, nw = 0;
#pragma omp parallel num_threads(s->threads)
    {
        if (omp_get_thread_num() == 0) {
            for (size_t c = 0; c < chunks; c++) {
                int seen = CHUNK_OPEN;
                if (!__atomic_compare_exchange_n(&state[c], &seen, CHUNK_WALKED, false,
                                                 __ATOMIC_ACQUIRE, __ATOMIC_ACQUIRE) &&
                    seen == CHUNK_FILTERED) {
                    np = walk_mask(taken, cand, mask, c, s->pair_moves, np);
                    continue;
                }
                const size_t k0 = c * SIM_RESOLVE_CHUNK;
                const size_t k1 = count - k0 < SIM_RESOLVE_CHUNK ? count : k0 + SIM_RESOLVE_CHUNK;
                np = walk_range(taken, cand, k0, k1, s->pair_moves, np);
            }
            nw = walk_walls(s, taken, s->wall_moves);
        } else {
            for (;;) {
                const size_t c = __atomic_fetch_add(&next, 1, __ATOMIC_RELAXED);
                if (c >= chunks)
                    break;
                int seen = CHUNK_OPEN;
                if (!__atomic_compare_exchange_n(&state[c], &seen, CHUNK_FILTERING, false,
                                                 __ATOMIC_RELAXED, __ATOMIC_RELAXED))
                    continue;
                filter_chunk(taken, cand, mask, c, count);
                __atomic_store_n(&state[c], CHUNK_FILTERED, __ATOMIC_RELEASE);
            }
        }
    }
    *np_out = np;
    *nw_out = nw;
    return 0;
}

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
 * Every candidate is written to its list of accepted moves, which advances only past accepted
 * ones. The flags are counted and cleared by the motion's pass over every particle
 * (sim_step.c's move_free). */
int sim_resolve(sim_stepper *s, size_t count, sim_stats *stats)
{
    size_t np = 0, nw = 0;
    if (s->parallel && count >= SIM_RESOLVE_TEAM_MIN) {
        if (resolve_team(s, count, &np, &nw))
            return -1;
    } else {
        np = walk_range(s->taken, s->merged, 0, count, s->pair_moves, 0);
        nw = walk_walls(s, s->taken, s->wall_moves);
    }
    s->wall_moves_len = nw;
    s->pair_moves_len = np;
    stats->wall_collisions += nw;
    stats->pair_collisions += np;
    return 0;
}
