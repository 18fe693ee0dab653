/*
 * sim_core.h: the core's own interfaces (input, generator, stepping, output), used by the
 * command line (sim_main.c) and by the C tests. Variants include only sim.h.
 */
#ifndef SIM_CORE_H
#define SIM_CORE_H

#include <float.h>
#include <stdio.h>

#include "sim.h"

/* Exit statuses (SPEC §1). */
enum { SIM_EXIT_OK = 0, SIM_EXIT_RUNTIME = 1, SIM_EXIT_USAGE = 2 };

/* Message buffer length: one line of stderr. */
#define SIM_MSG_LEN 256

typedef enum sim_mode { SIM_MODE_PRINT, SIM_MODE_PERF } sim_mode;

/* The first two lines of the input, in the types SPEC gives them. */
typedef struct sim_header {
    int32_t n;
    double L, r;
    int64_t steps;
    sim_mode mode;
} sim_header;

/* An input error: the line it is on (from 1) and what rule was broken. */
typedef struct sim_error {
    long line;
    char what[SIM_MSG_LEN];
} sim_error;

/* A tokenizer over the whole input text that remembers line numbers. */
typedef struct sim_lexer {
    const char *text, *end;
    long line;
} sim_lexer;

void sim_lexer_init(sim_lexer *lx, const char *text, size_t len);

/* The first n bytes of s for a message, NUL-terminated in buf: printable ASCII as it is, every
 * other byte and the backslash as \xNN. Stops short where buf is full; returns the length. */
size_t sim_escape(char *buf, size_t len, const char *s, size_t n);
/* A buffer that holds n bytes escaped, NUL included. */
#define SIM_ESCAPED_MAX(n) (4 * (n) + 1)

/* Parse "N L r S" and MODE. Returns 0, or -1 with *err set. */
int sim_parse_header(sim_lexer *lx, sim_header *h, sim_error *err);

/* Parse the listed particles into w (already allocated for h->n) and mark them in `listed`.
 * Returns 0, or -1 with *err set. */
int sim_parse_particles(sim_lexer *lx, const sim_header *h, sim_world *w, unsigned char *listed,
                        sim_error *err);

/* SPEC §4: fill every particle not marked in `listed`, in increasing index order, from one
 * splitmix64 stream seeded with `seed`. Generation is done in double for every build, so all
 * builds start from the same state rounded to their real type. */
void sim_generate(sim_world *w, const sim_header *h, const unsigned char *listed, uint64_t seed);

/* The generator itself, exposed for the tests. */
uint64_t sim_splitmix64_next(uint64_t *state);
double sim_uniform(uint64_t *state);

/* World memory. Returns 0, or -1 when memory is short (nothing leaked). */
int sim_world_alloc(sim_world *w, const sim_header *h);
void sim_world_free(sim_world *w);
/* Bytes the simulation needs per particle, for refusing an N this machine cannot hold. */
size_t sim_bytes_per_particle(void);

/* Counters a run accumulates, for --timing. */
typedef struct sim_stats {
    uint64_t pair_tests;
    uint64_t candidates;
    uint64_t pair_collisions;
    uint64_t wall_collisions;
    /* Seconds in each phase of sim_step, summed over the run (where the time goes), timed on the
     * thread that calls sim_step around whole phases: broad_s the variant's find_pairs, walls_s
     * the wall candidates, sort_s merging and sorting the candidates, resolve_s the greedy walk,
     * motion_s moving the discs. Their sum is at most the time in sim_step; the rest is region
     * starts and barriers (sim_step.c says which). */
    double broad_s, walls_s, sort_s, resolve_s, motion_s;
} sim_stats;

/* Per-run stepping state: candidate buffers, the merged list, scratch arrays. */
typedef struct sim_stepper sim_stepper;

sim_stepper *sim_stepper_create(const sim_world *w, const sim_variant *v, int threads);

/* One candidate writer's work over the run so far, for --timing: seconds in the finder's loops
 * (as the variant timed them; 0 where it does not), pairs tested, chunks it was dealt. */
typedef struct sim_thread_work {
    double busy_s;
    uint64_t pairs;
    uint64_t chunks;
} sim_thread_work;

/* The number of candidate writers (the sink's buffers: the threads, or T*T for p3). */
int sim_stepper_writers(const sim_stepper *s);
/* Writer k's work so far, k in [0, sim_stepper_writers(s)). */
sim_thread_work sim_stepper_work(const sim_stepper *s, int k);
/* Start the OpenMP team of `threads` threads and move each once to its own CPU, then let it
 * move freely again (sim_team.c says why). Nothing for fewer than 2 threads or off Linux. */
void sim_team_spread(int threads);
void sim_stepper_destroy(sim_stepper *s);
/* Advance the world by one step (SPEC §2). Returns 0, or -1 when memory ran out. The stepper
 * keeps the wall candidates of the state it leaves, for the next step: between steps, change
 * the world only through sim_step (or make a new stepper). The world's pcoll and wcoll are
 * complete once the stepper is destroyed (it keeps the latest steps' counts until then). */
int sim_step(sim_stepper *s, sim_world *w, sim_stats *stats);
/* From this many pairs that a wall does not come first for, a parallel stepper's greedy walk
 * runs on its team (sim_resolve.c): a region's start costs microseconds, the walk about 5 ns a
 * pair at a million particles (docs/grid_bound.md). The sort's team bound; the walk's own
 * break-even is not measured. */
#define SIM_RESOLVE_TEAM_MIN 65536
/* Sort candidates by the SPEC §2 key (t; pair before wall; i; j); tmp holds n items. Returns
 * 0, or -1 when memory ran out (a in its order then). */
int sim_sort_candidates(sim_cand *a, sim_cand *tmp, size_t n);

/* The moves of accepted collisions (sim_motion.c), events[k0, k0 + sim_event_block()) of
 * `count` accepted wall candidates (sim_move_walls) or pair candidates (sim_move_pairs), from
 * the world's state. sim_move_walls writes the new positions into nx, ny and the new
 * velocities into the world's vx, vy; so does sim_move_pairs when out is NULL, and otherwise
 * it writes pair k's new states to out[SIM_PAIR_OUT * k ...] (x, y, vx, vy of its i, then of
 * its j) and changes nothing else.
 * The caller counts the collisions in pcoll / wcoll. Blocks touch only their own particles
 * and read a particle's state before they write it, so they may run on any threads in any
 * order. */
#define SIM_PAIR_OUT 8
size_t sim_event_block(void);
void sim_move_walls(const sim_world *w, const sim_cand *events, size_t count, size_t k0,
                    sim_real *nx, sim_real *ny);
void sim_move_pairs(const sim_world *w, const sim_cand *events, size_t count, size_t k0,
                    sim_real *out, sim_real *nx, sim_real *ny);

/* SPEC §2 wall time of one particle: min over the axes; SIM_REAL_INF when it never hits. The
 * scalar reference: the stepper finds every particle's in a vectorised pass of its own, which
 * the tests hold to this one (sim_stepper_wall_time). */
sim_real sim_wall_time(const sim_world *w, int32_t i);
/* Particle i's wall time as the stepper holds it for the world's state after a sim_step. */
sim_real sim_stepper_wall_time(const sim_stepper *s, int32_t i);

/* Output (SPEC §3). Return 0, or -1 on a write error. */
int sim_write_state(FILE *out, const sim_world *w, int64_t step, bool precise);
int sim_write_final(FILE *out, const sim_world *w, int64_t step, bool precise);

/* --describe: the variant's facts (sim_variant) as one line of JSON, keys in the order name,
 * summary, exact, parallel, all_pairs, repairs (null when it repairs none), mpi, sync. Returns
 * 0, or -1 on a write error. */
int sim_describe(FILE *out, const sim_variant *v);

/* --replay (sim_replay.c): the successor of each state in `text` (len bytes), with the rules
 * of this binary's variant on `threads` threads, written to out. Returns an exit status after
 * printing any error (one line on stderr). */
int sim_replay(FILE *out, const char *name, const char *text, size_t len, int threads);

/* The longest real sim_format_real writes, its NUL included: %.8f of the largest finite value
 * of the build's real type (a sign, its integer digits, the point, 8 decimals) is the longest
 * of its formats, so every finite value is printed in full (a NaN or an infinity is short).
 * Single-precision builds format through double. */
#if defined(SIM_REAL_F128)
#define SIM_REAL_INT_DIGITS (FLT128_MAX_10_EXP + 1)
#else
#define SIM_REAL_INT_DIGITS (DBL_MAX_10_EXP + 1)
#endif
#define SIM_REAL_TEXT_MAX (1 + SIM_REAL_INT_DIGITS + 1 + 8 + 1)

/* Format one real with %.8f, or %.17g when precise, into buf; a buffer of SIM_REAL_TEXT_MAX
 * holds any value. */
void sim_format_real(char *buf, size_t len, sim_real v, bool precise);
/* printf("%.8f", v) at p, unterminated; returns the length, or 0 outside its exact fast path
 * (|v| >= 1e10, NaN, infinities), where the caller uses the C library. */
size_t sim_fixed8(char *p, double v);

#endif /* SIM_CORE_H */
