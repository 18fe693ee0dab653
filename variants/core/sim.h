/*
 * sim.h: what a variant sees of the core.
 *
 * The core (variants/core/) owns the model once: input, particle generation, contact times,
 * sorting and greedy resolution, motion, counters, output and the command line. A variant
 * (variants/NAME.c) contributes one thing: how candidate *pairs* are found in a step. It
 * defines `const sim_variant sim_variant_def` and nothing else that is global.
 *
 * Determinism: a finder may find candidates in any order and on any thread, into any of the
 * candidate buffers it was given. The core merges the buffers and sorts them by the total
 * SPEC key (t, pair before wall, i, j) before resolving, so the result is the same for every
 * thread count and schedule. A finder must report each pair at most once, with i < j.
 *
 * A variant may run as several processes (MPI ranks: sim_variant's `ranks`), each holding the
 * whole world and running the same steps; its finder then exchanges the candidates, so that
 * every rank sorts and resolves the same list. The core itself never calls MPI: only such a
 * variant's own files are compiled with mpicc.
 */
#ifndef SIM_H
#define SIM_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include <omp.h>

#include "sim_real.h"

/* Largest particle count: indices are int32_t so a candidate stays 16 bytes in double. */
#define SIM_N_MAX INT32_MAX

/* The j of a wall candidate. Pairs have 0 <= i < j. */
#define SIM_WALL ((int32_t)-1)

/* Length of the j-range one call of sim_scan_tile covers: long enough for the vectorised
 * kernel to amortise its setup, short enough to spread a row over many threads. */
#define SIM_TILE 256

/* The simulated system, structure of arrays so the pair kernel vectorises.
 * Units: lengths in the input's length unit, time in steps, velocities in length per step. */
typedef struct sim_world {
    int32_t n;
    sim_real L;     /* side of the square box */
    sim_real r;     /* radius of every disc */
    sim_real lo;    /* r: the smallest allowed centre coordinate */
    sim_real hi;    /* L - r: the largest allowed centre coordinate */
    sim_real diam2; /* (2r)*(2r), computed once exactly as SPEC writes it */
    sim_real *x, *y, *vx, *vy;
    int64_t *pcoll, *wcoll; /* accepted pair / wall collisions per particle */
} sim_world;

/* One candidate collision of this step: contact time t in [0, 1] (steps), particles i < j,
 * or j == SIM_WALL for a wall. */
typedef struct sim_cand {
    sim_real t;
    int32_t i;
    int32_t j;
} sim_cand;

/* A growable candidate buffer written by one thread at a time. Aligned to a cache line so
 * that threads appending to neighbouring buffers do not share lines. */
typedef struct sim_cand_buf {
    _Alignas(64) sim_cand *items;
    size_t len, cap;
    uint64_t pair_tests; /* pairs examined this step, for --timing */
    bool failed;         /* an allocation failed: the core ends the run with status 1 */
    /* Pairs the finder found and left out because a wall of one of their particles comes
     * first (sim_pair_sink's wall_t): the core counts them among the candidates (--timing), as
     * if they had been pushed and dropped by its sort. Reset by the core every step. */
    uint64_t dropped;
    /* For --timing's per-thread figures, summed over the run (never reset by the core): the
     * seconds this buffer's writer spent in the finder's loops (sim_busy_start/stop, once per
     * thread per region, so the timers cost nothing per pair) and the chunks of iterations the
     * OpenMP runtime handed it. */
    double busy_s;
    uint64_t chunks;
} sim_cand_buf;

/* What a finder writes into: `count` buffers, one per concurrent writer. */
typedef struct sim_pair_sink {
    sim_cand_buf *bufs;
    int count;
    int threads;   /* the thread count of this run (--threads / OMP_NUM_THREADS) */
    void *scratch; /* the variant's own per-run memory (see scratch_create) */
    /* Every particle's wall time in the world's current state (SPEC §2's tw; above 1, or
     * infinite, where no wall is met within the step), valid while find_pairs runs. The core
     * drops a pair (i, j, t) with wall_t[i] < t or wall_t[j] < t before it sorts (the walk would
     * refuse it and it changes nothing else); a finder may leave such pairs out itself, counting
     * them in its buffer's `dropped`. */
    const sim_real *wall_t;
} sim_pair_sink;

/* How many times a finder asks the OpenMP runtime for one operation in a step, as a function
 * of the scene's N: per_step + per_row * N + per_pair * N(N-1)/2 + per_tile * (the tiles of
 * `sim_sync.tile` j of every row: the sum over rows i of ceil((N-1-i) / tile)). */
typedef struct sim_count {
    int per_step, per_row, per_pair, per_tile;
} sim_count;

/* What a finder asks of the OpenMP runtime in a step (`--describe`'s "sync"): the report
 * multiplies each count by the cost of one operation at the run's thread count (build/ompcost)
 * to explain what a strategy pays for its structure. */
typedef struct sim_sync {
    sim_count regions;        /* parallel regions entered: a team fork and its closing barrier */
    sim_count nested_regions; /* regions forked inside a region by each of its T threads, T at a
                                 time (p3's team per row) */
    sim_count barriers;       /* barriers inside a region, beyond its closing one */
    sim_count grabs;          /* chunks taken from a dynamic schedule's shared counter */
    int32_t tile;             /* j per tile, for per_tile */
} sim_sync;

/* What the core asks of a variant that runs as several processes (MPI ranks), each holding the
 * whole world (sim_variant's `ranks`; NULL for a variant of one process). Every rank runs the
 * same steps on the same state; rank 0 reads the input and writes the output and every message
 * about the input or the command line. Except rank, size and abort, each function is called by
 * every rank at the same point of the run (a collective call), so that none waits for ever. */
typedef struct sim_ranks {
    /* Whether a launcher started this process as one of its ranks. Alone, a run that asks only
     * what the binary is (--describe, --help) starts no ranks. */
    bool (*launched)(void);
    /* First thing in main, with main's arguments. Returns 0, or nonzero after printing why
     * (the run then ends with status 1). */
    int (*start)(int *argc, char ***argv);
    /* Last thing on every way out of main after a successful start. */
    void (*stop)(void);
    /* This process's rank, in [0, size()), and the number of ranks. */
    int (*rank)(void);
    int (*size)(void);
    /* Rank 0's input to every rank: on rank 0 `text` is what it read (len bytes, malloc'd, a
     * NUL after them), or NULL where it could not read (it said why); elsewhere NULL. Returns
     * this rank's copy (rank 0's is `text` itself), with its length in *len; NULL on every rank
     * where rank 0 had none. */
    char *(*share_input)(char *text, size_t *len);
    /* The largest of the ranks' values (exit statuses, counts). */
    int (*largest)(int value);
    /* Ends every rank at once with `status`: what a rank does on a failure of its own in the
     * middle of the steps, where the others would wait for it. Does not return. */
    void (*abort)(int status);
    /* Rank 0 receives every rank's `bytes` bytes at `mine` into `all`, in rank order (size() *
     * bytes; `all` is not written on the other ranks). */
    void (*gather)(const void *mine, size_t bytes, void *all);
    /* --timing: writes the variant's own fields, each as `, "key": value`, to out on rank 0
     * (out is NULL on the others). */
    void (*timing)(FILE *out);
} sim_ranks;

/* A variant: what it says about itself (`--describe` prints these facts as one JSON line, so
 * that the harness and the test scripts read them from the binary instead of keeping lists of
 * their own), then how it finds candidates. */
typedef struct sim_variant {
    const char *name;
    const char *summary; /* one sentence: how it finds candidate pairs */
    bool exact;          /* promises output byte-identical to seq */
    bool parallel;       /* uses threads; false: runs on one whatever --threads says */
    /* Runs seq's pair test (the shared kernel) on every pair i < j, so that its speedup over
     * seq is parallelism alone; false for finders that skip pairs or test them their own way. */
    bool all_pairs;
    const char *repairs; /* the seed strategy whose pathology this variant repairs, or NULL */
    /* Runs as MPI ranks (under mpirun, or alone as one): `ranks` below is set. */
    bool mpi;
    /* Its runtime operations per step; NULL where they depend on more than N (the data, as
     * grid's barriers; OMP_SCHEDULE, as p1_runtime's chunks). */
    const sim_sync *sync;
    /* Candidate buffers the finder needs for `threads` threads; NULL means `threads`. */
    int (*buffer_count)(int threads);
    /* Optional per-run memory, e.g. a grid. Return NULL on allocation failure. */
    void *(*scratch_create)(const sim_world *w, int threads);
    void (*scratch_destroy)(void *scratch);
    /* Append every pair candidate of the current state (SPEC §2) to the sink's buffers. */
    void (*find_pairs)(const sim_world *w, sim_pair_sink *sink);
    /* How the processes of an MPI variant work together; NULL for every other variant. */
    const sim_ranks *ranks;
} sim_variant;

/* Defined by exactly one variant file per binary. */
extern const sim_variant sim_variant_def;

/* ---- The shared kernel, for finders ---- */

/* SPEC §2 pair test for i < j. True and *t set when the pair is a candidate (t <= 1). */
bool sim_pair_time(const sim_world *w, int32_t i, int32_t j, sim_real *t);

/* Append a candidate; on allocation failure marks the buffer failed and drops it. */
void sim_cand_push(sim_cand_buf *buf, sim_real t, int32_t i, int32_t j);

/* Test particle i against every j in [j_begin, j_end) (all j > i) and append candidates.
 * Vectorised; counts the pairs in buf->pair_tests. */
void sim_scan_row(const sim_world *w, int32_t i, int32_t j_begin, int32_t j_end,
                  sim_cand_buf *buf);

/* The number of SIM_TILE-long tiles of row i (j in [i+1, n)), and one tile's scan: lets a
 * finder hand out a row's j-range to threads without calling the kernel once per j. */
int32_t sim_row_tiles(const sim_world *w, int32_t i);
void sim_scan_tile(const sim_world *w, int32_t i, int32_t tile, sim_cand_buf *buf);

/* ---- Per-thread work, for --timing ---- */

/* A thread's share of a parallel region: t0 = sim_busy_start() before its loop, and
 * sim_busy_stop(buf, t0) after it, before any barrier (so the loop is `omp for ... nowait` and
 * the region's end is the barrier): waiting is not work. */
static inline double sim_busy_start(void)
{
    return omp_get_wtime();
}

static inline void sim_busy_stop(sim_cand_buf *buf, double t0)
{
    buf->busy_s += omp_get_wtime() - t0;
}

/* ---- The seed's loop shapes (sim_loops.c), for finders that use one ---- */

/* How a finder tests one row: particle i against the j it is responsible for. */
typedef void sim_row_scan_fn(const sim_world *w, int32_t i, sim_cand_buf *buf);

/* Row i against every j > i with the shared kernel. */
void sim_scan_full_row(const sim_world *w, int32_t i, sim_cand_buf *buf);

/* Outer loop parallel: one region, rows shared out by the `omp for` schedule each name says,
 * each thread writing buffer omp_get_thread_num():
 *   sim_rows_static   schedule(static)     one contiguous block of rows per thread (the seed's p1)
 *   sim_rows_cyclic   schedule(static, 1)  rows dealt round-robin
 *   sim_rows_dynamic  schedule(dynamic)    one row per grab from a shared counter (p1d)
 *   sim_rows_runtime  schedule(runtime)    whatever OMP_SCHEDULE says (the schedule study) */
void sim_rows_static(const sim_world *w, sim_pair_sink *sink, sim_row_scan_fn *scan);
void sim_rows_cyclic(const sim_world *w, sim_pair_sink *sink, sim_row_scan_fn *scan);
void sim_rows_dynamic(const sim_world *w, sim_pair_sink *sink, sim_row_scan_fn *scan);
void sim_rows_runtime(const sim_world *w, sim_pair_sink *sink, sim_row_scan_fn *scan);

/* The buffer a writer uses; `slot` in [0, sink->count). */
static inline sim_cand_buf *sim_sink_buf(sim_pair_sink *sink, int slot)
{
    return &sink->bufs[slot];
}

#endif /* SIM_H */
