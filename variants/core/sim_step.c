/*
 * sim_step.c: one step of SPEC §2, shared by every variant, as phases in order:
 *
 *   1. candidates: wall candidates (one buffer per thread, in particle order, and every
 *      particle's wall time in wall_t; found by the wall pass at the end of the step before,
 *      or here for a first step: sim_walls.c) and pair candidates (the variant's finder, into
 *      per-writer buffers);
 *   2. the pairs sorted by the total key (t, i, j), less those a wall comes first for
 *      (sim_sort.c);
 *   3. the greedy walk over all candidates in key order (t, pair before wall, i, j), accepting
 *      a candidate when neither particle has been accepted yet (sim_resolve.c);
 *   4. every particle moves exactly once, reading the old state and writing a new one, so the
 *      motion can run in parallel without races and with thread-independent results: all by
 *      their velocity, then the accepted collisions over their own particles (sim_motion.c);
 *      the new state's wall candidates are found right after, in the same region.
 * Phases 2-4 are built to cost little next to the finder: no branch on a random outcome in a
 * loop over particles or candidates, vectorised passes over particles, streams instead of
 * scattered accesses to cold memory.
 *
 * Why per-writer buffers and not the seed's shared array behind `omp critical`: the critical
 * section serialised every candidate append (the report's bottleneck), and the order in which
 * threads entered it was the order candidates were found, which is not reproducible. Private
 * buffers need no lock; the sort makes the order irrelevant.
 */
#include <stdint.h>
#include <stdlib.h>

#include <omp.h>

#include "sim_stepper.h"

static inline sim_real clamp(sim_real q, sim_real lo, sim_real hi)
{
    return q < lo ? lo : (q > hi ? hi : q);
}

/* Particles [0, len) of the given arrays move by their whole velocity (no collision), from
 * the world's positions into the next ones; the collisions the walk accepted are counted and
 * their flags cleared for the next walk. The counts go into bytes, added to the world's
 * 64-bit pcoll and wcoll every SIM_COUNT_FLUSH steps: an increment per event missed the cache
 * (nothing else in a step touches the counts), and a 64-bit add per particle and step
 * streamed 32 bytes (0.5 ms of the report benchmark's 50 steps). A function of its own so
 * that GCC sees restrict pointers (in the parallel region they are loads from the region's
 * shared data) and vectorises. */
static void move_free(sim_real *restrict nx, sim_real *restrict ny, const sim_real *restrict x,
                      const sim_real *restrict y, const sim_real *restrict vx,
                      const sim_real *restrict vy, unsigned char *restrict pair_count,
                      unsigned char *restrict wall_count, unsigned char *restrict taken,
                      int32_t len, sim_real lo, sim_real hi)
{
    for (int32_t i = 0; i < len; i++) {
        nx[i] = clamp(x[i] + vx[i], lo, hi);
        ny[i] = clamp(y[i] + vy[i], lo, hi);
    }
    for (int32_t i = 0; i < len; i++) {
        pair_count[i] += taken[i] & SIM_TAKEN_PAIR;
        wall_count[i] += taken[i] >> 1;
        taken[i] = 0;
    }
}

/* Blocks [b0, b1) of the world's particles move by their velocity (move_free), a block at a
 * time. */
static void move_free_blocks(sim_stepper *s, const sim_world *w, int32_t b0, int32_t b1)
{
    const int32_t n = w->n;
    for (int32_t b = b0; b < b1; b++) {
        int32_t j0, j1;
        sim_block_span(n, b, b + 1, &j0, &j1);
        move_free(s->nx + j0, s->ny + j0, w->x + j0, w->y + j0, w->vx + j0, w->vy + j0,
                  s->pair_count + j0, s->wall_count + j0, s->taken + j0, j1 - j0, w->lo, w->hi);
    }
}

/* The accepted walls of particles [i0, i1): the run [*k0, *k1) of the particle-ordered list. */
static void wall_run(const sim_cand *wall_moves, size_t nw, int32_t i0, int32_t i1, size_t *k0,
                     size_t *k1)
{
    size_t lo = 0, hi = nw;
    while (lo < hi) { /* first k with i >= i0 */
        const size_t mid = lo + (hi - lo) / 2;
        if (wall_moves[mid].i < i0)
            lo = mid + 1;
        else
            hi = mid;
    }
    *k0 = lo;
    for (hi = lo; hi < nw && wall_moves[hi].i < i1;)
        hi++;
    *k1 = hi;
}

/* The new states of the accepted pairs' particles in [i0, i1), copied from pair_out. */
static void copy_pair_states(sim_stepper *s, sim_world *w, int32_t i0, int32_t i1)
{
    const sim_cand *pair_moves = s->pair_moves;
    for (size_t k = 0; k < s->pair_moves_len; k++)
        for (int side = 0; side < 2; side++) {
            const int32_t i = side ? pair_moves[k].j : pair_moves[k].i;
            if (i < i0 || i >= i1)
                continue;
            const sim_real *o = s->pair_out + SIM_PAIR_OUT * k + 4 * side;
            s->nx[i] = o[0];
            s->ny[i] = o[1];
            w->vx[i] = o[2];
            w->vy[i] = o[3];
        }
}

/* Phase 4 on one thread: the same moves in the same order as the team's (move_team) with no
 * barrier to spare, the pairs written straight into the next state (the copy through pair_out
 * cost 1 ms of the report benchmark), then the next state's wall candidates. Sets the seconds
 * of the motion and of the wall pass. */
static void move_alone(sim_stepper *s, sim_world *w, double *motion_s, double *walls_s)
{
    const int32_t n = w->n;
    const size_t nw = s->wall_moves_len, np = s->pair_moves_len, eb = sim_event_block();
    const double m0 = omp_get_wtime();
    move_free_blocks(s, w, 0, (n + SIM_WALL_BLOCK - 1) / SIM_WALL_BLOCK);
    for (size_t k = 0; k < nw; k += eb)
        sim_move_walls(w, s->wall_moves, nw, k, s->nx, s->ny);
    for (size_t k = 0; k < np; k += eb)
        sim_move_pairs(w, s->pair_moves, np, k, NULL, s->nx, s->ny);
    const double m1 = omp_get_wtime();
    sim_find_walls_range(&s->walls[0], s->wall_t, s->nx, s->ny, w->vx, w->vy, w->lo, w->hi, 0, n);
    *motion_s = m1 - m0;
    *walls_s = omp_get_wtime() - m1;
}

/* Phase 4 on the team, then the next step's wall candidates, in one parallel region with one
 * barrier (on a loaded machine a barrier can wait a scheduler tick for a descheduled thread):
 *  1. each thread for its own run of particles (sim_share): all move by their velocity into
 *     the next positions (vectorised; most have no collision: 55% on the report benchmark),
 *     which also brings the old state into the caches for 2;
 *  2. the accepted pairs' new states, into pair_out (reading the old state only), shared out
 *     by blocks of pairs; the barrier;
 *  3. each thread for its own particles: the accepted walls move (the wall list is in particle
 *     order), the pair states are copied from pair_out;
 *  4. the same thread, the wall candidates of its particles' new state.
 * Before the barrier nothing writes the old state; after it a thread writes only its own
 * particles and reads nothing another wrote after the barrier, so 3 and 4 need none.
 * Timed on thread 0, the thread that calls sim_step: *motion_s from the region's start to the
 * end of its 3 (the barrier included), *walls_s its 4; the region's start-up before thread 0
 * runs and the closing barrier are in neither, but in sim_s. Returns 0, or -1 when memory ran
 * out. */
static int move_team(sim_stepper *s, sim_world *w, double *motion_s, double *walls_s)
{
    const int32_t n = w->n;
    const size_t nw = s->wall_moves_len, np = s->pair_moves_len, eb = sim_event_block();
    const int32_t blocks = (n + SIM_WALL_BLOCK - 1) / SIM_WALL_BLOCK;
    const int32_t pair_blocks = (int32_t)((np + eb - 1) / eb);
    if (np > s->pair_out_cap) {
        sim_real *p = realloc(s->pair_out, np * SIM_PAIR_OUT * sizeof *p);
        if (!p)
            return -1;
        s->pair_out = p;
        s->pair_out_cap = np;
    }
    double motion = 0, walls = 0;
#pragma omp parallel num_threads(s->threads)
    {
        const int me = omp_get_thread_num();
        const double m0 = me == 0 ? omp_get_wtime() : 0;
        int32_t b0, b1, i0, i1;
        sim_share(blocks, me, omp_get_num_threads(), &b0, &b1);
        sim_block_span(n, b0, b1, &i0, &i1);
        move_free_blocks(s, w, b0, b1);
#pragma omp for schedule(static)
        for (int32_t b = 0; b < pair_blocks; b++)
            sim_move_pairs(w, s->pair_moves, np, (size_t)b * eb, s->pair_out, NULL, NULL);
        size_t k0, k1;
        wall_run(s->wall_moves, nw, i0, i1, &k0, &k1);
        for (size_t k = k0; k < k1; k += eb)
            sim_move_walls(w, s->wall_moves, k1, k, s->nx, s->ny);
        copy_pair_states(s, w, i0, i1);
        const double m1 = me == 0 ? omp_get_wtime() : 0;
        sim_find_walls_range(&s->walls[me], s->wall_t, s->nx, s->ny, w->vx, w->vy, w->lo, w->hi,
                             i0, i1);
        if (me == 0) {
            motion = m1 - m0;
            walls = omp_get_wtime() - m1;
        }
    }
    *motion_s = motion;
    *walls_s = walls;
    return 0;
}

static void swap_arrays(sim_real **a, sim_real **b)
{
    sim_real *t = *a;
    *a = *b;
    *b = t;
}

/* Seconds since *t, and *t moved to now: each phase's time starts where the last one's ended. */
static double lap(double *t)
{
    const double now = omp_get_wtime(), d = now - *t;
    *t = now;
    return d;
}

int sim_step(sim_stepper *s, sim_world *w, sim_stats *stats)
{
    /* 1. Candidates. */
    double t = omp_get_wtime();
    if (!s->walls_ready) {
        sim_find_walls(s, w);
        stats->walls_s += lap(&t);
    }
    s->walls_ready = false;
    s->variant->find_pairs(w, &s->sink);
    stats->broad_s += lap(&t);
    /* 2. Sort. */
    const size_t count = sim_merge_candidates(s, stats);
    if (count == (size_t)-1)
        return -1;
    stats->sort_s += lap(&t);
    /* 3. Resolution. */
    if (sim_resolve(s, count, stats))
        return -1;
    stats->resolve_s += lap(&t);
    /* 4. Motion, and the wall candidates of the new state. */
    sim_clear_walls(s);
    double motion_s = 0, walls_s = 0;
    if (!sim_team_pays(s, w->n))
        move_alone(s, w, &motion_s, &walls_s);
    else if (move_team(s, w, &motion_s, &walls_s))
        return -1;
    stats->motion_s += motion_s;
    stats->walls_s += walls_s;
    swap_arrays(&w->x, &s->nx);
    swap_arrays(&w->y, &s->ny);
    s->walls_ready = true;
    if (++s->unflushed == SIM_COUNT_FLUSH)
        sim_flush_counts(s);
    return 0;
}
