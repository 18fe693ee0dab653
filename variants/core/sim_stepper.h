/*
 * sim_stepper.h: what the files of one step share, and nothing else includes: the stepper's
 * state and the phases of sim_step (SPEC §2), each in a file of its own:
 *
 *   sim_stepper.c  the stepper's memory and counters (create, destroy, --timing's figures);
 *   sim_walls.c    the wall candidates and every particle's wall time;
 *   sim_sort.c     the pair candidates merged and sorted by the SPEC key;
 *   sim_resolve.c  the greedy walk that accepts candidates (on the team when it pays);
 *   sim_motion.c   the moves of the accepted collisions, in vector lanes;
 *   sim_step.c     the step itself: the phases in order, and the motion of every particle.
 *
 * The command line and the tests see the stepper through sim_core.h only.
 */
#ifndef SIM_STEPPER_H
#define SIM_STEPPER_H

#include "sim_core.h"

/* Below this many particles the per-particle loops (wall times, motion) are not worth a
 * parallel region (see sim_team_pays). */
#define SIM_PARALLEL_MIN 4096

/* Bytes per cache line, for prefetching a whole array. */
#define SIM_CACHE_LINE 64

/* Steps after which the byte counts of collisions are added to the world's (a particle has
 * at most one collision a step, so a byte holds this many). */
#define SIM_COUNT_FLUSH 255

/* Particles per block of the wall pass and of the motion's pass over every particle: the
 * wall pass's distances stay in stack arrays (L1) between its vectorised loops. */
#define SIM_WALL_BLOCK 256

/* taken[i] after the greedy walk: the kind of particle i's accepted collision, if any. */
#define SIM_TAKEN_PAIR 1
#define SIM_TAKEN_WALL 2

struct sim_stepper {
    const sim_variant *variant;
    int threads;
    bool parallel;
    sim_pair_sink sink;
    sim_cand_buf *walls; /* the wall candidates of the world's state, one buffer per thread */
    bool walls_ready;    /* walls were found by the last step's wall pass (see sim_step) */
    sim_cand *merged; /* this step's pair candidates that a wall does not come first for, sorted */
    size_t merged_cap;
    uint32_t *hist; /* the sort's histogram (sim_sort.c) */
    size_t hist_cap;
    /* The finder's candidate buffers as the sort reads them. */
    sim_cand **sources;
    size_t *source_len;
    /* The candidates the greedy walk accepted, walls and pairs apart, in walk order. */
    sim_cand *wall_moves, *pair_moves;
    size_t wall_moves_cap, pair_moves_cap, wall_moves_len, pair_moves_len;
    /* The team's walk (sim_resolve.c): each chunk's state and survivor mask, for chunk_cap
     * chunks. */
    int *chunk_state;
    uint64_t *chunk_mask;
    size_t chunk_cap;
    /* The accepted pairs' new states, SIM_PAIR_OUT reals each, where a team moves them (see
     * sim_step.c). */
    sim_real *pair_out;
    size_t pair_out_cap; /* in pairs */
    unsigned char *taken; /* n + 1 flags, all 0 between walks (see sim_resolve.c) */
    sim_real *wall_t;     /* each particle's wall time in the world's state (see sim_resolve.c) */
    /* Collisions of each kind per particle not yet added to the world's pcoll / wcoll (see
     * sim_step.c's move_free), added every SIM_COUNT_FLUSH steps and by sim_stepper_destroy. */
    unsigned char *pair_count, *wall_count;
    int64_t *pcoll, *wcoll; /* the world's counts they are added to */
    int32_t n;
    int unflushed; /* steps counted since the last flush */
    /* The next positions, swapped with the world's arrays. Velocities change in place: only
     * the moves of accepted collisions change them, each its own particles' (sim_motion.c). */
    sim_real *nx, *ny;
    uint64_t *writer_pairs; /* pair tests per candidate buffer over the run */
};

/* Whether the per-particle loops of a world of n particles (wall times, motion) run on the
 * stepper's team: the one home of the SIM_PARALLEL_MIN rule. */
static inline bool sim_team_pays(const sim_stepper *s, int32_t n)
{
    return s->parallel && n >= SIM_PARALLEL_MIN;
}

/* Thread `me` of `team`'s share of [0, blocks): [*b0, *b1), contiguous and in thread order, so
 * that each thread's wall buffer holds a run of particles and the buffers follow each other
 * in particle order. */
static inline void sim_share(int32_t blocks, int me, int team, int32_t *b0, int32_t *b1)
{
    *b0 = (int32_t)((int64_t)blocks * me / team);
    *b1 = (int32_t)((int64_t)blocks * (me + 1) / team);
}

/* Particles [i0, i1) of the block range [b0, b1) of n particles (blocks of SIM_WALL_BLOCK). */
static inline void sim_block_span(int32_t n, int32_t b0, int32_t b1, int32_t *i0, int32_t *i1)
{
    *i0 = b0 * SIM_WALL_BLOCK;
    *i1 = (int64_t)b1 * SIM_WALL_BLOCK < n ? b1 * SIM_WALL_BLOCK : n;
    if (*i0 > *i1)
        *i0 = *i1;
}

/* ---- sim_stepper.c ---- */

/* Room for `need` candidates in *items (capacity *cap, grown by doubling). False when memory
 * ran out (*items unchanged). */
bool sim_cand_reserve(sim_cand **items, size_t *cap, size_t need);
/* Add the counts of the steps since the last flush to the world's pcoll and wcoll. */
void sim_flush_counts(sim_stepper *s);

/* ---- sim_walls.c ---- */

/* Forget the wall candidates the stepper holds (before a pass finds the next ones). */
void sim_clear_walls(sim_stepper *s);
/* Append the wall candidates of particles [i0, i1) of the state (x, y, vx, vy) to buf, in
 * increasing i, and write every particle's wall time to wall_t. */
void sim_find_walls_range(sim_cand_buf *buf, sim_real *restrict wall_t,
                          const sim_real *restrict x, const sim_real *restrict y,
                          const sim_real *restrict vx, const sim_real *restrict vy, sim_real lo,
                          sim_real hi, int32_t i0, int32_t i1);
/* The wall candidates of the world's state, for a first step, each thread for its share;
 * later steps get them from the wall pass at the end of the step before. */
void sim_find_walls(sim_stepper *s, const sim_world *w);

/* ---- sim_sort.c ---- */

/* Sort the finder's pair candidates into s->merged, less those a wall comes first for (the
 * walls need no sorting: see sim_resolve.c), and make room for the walk's lists. Returns the
 * number of pairs kept, or (size_t)-1 when memory ran out. */
size_t sim_merge_candidates(sim_stepper *s, sim_stats *stats);

/* ---- sim_resolve.c ---- */

/* SPEC §2's greedy walk over the merged pairs and the walls: the accepted ones into
 * s->pair_moves and s->wall_moves, their particles flagged in s->taken; on the team when the
 * stepper is parallel and the pairs are many, with the same result. Returns 0, or -1 when
 * memory ran out. */
int sim_resolve(sim_stepper *s, size_t count, sim_stats *stats);

#endif /* SIM_STEPPER_H */
