/*
 * grid.h: what the pieces of the grid finder share, and nothing outside the grid variant (and
 * its unit tests) includes: the finder's constants and types, each piece's functions, and the
 * small helpers every piece's hot loops inline (the last section says why they are here).
 *
 *   variants/grid.c   the variant's definition
 *   grid_finder.c     the finder: the plan of a step, then its work items on the threads
 *   grid_state.c      the per-run and per-thread state and its memory
 *   grid_plan.c       the plan of a step: v_ref, K, cell size, padding and float margin, items
 *   grid_binning.c    a slice's entries in cell order: counting sort (dense) or radix (sparse)
 *   grid_prefilter.c  the pairs the float prefilter passes: the queue and the decision in double
 *   grid_runs.c       which runs each entry is looked at against (the lo-corner rule)
 *   grid_scan.c       a work item: slices binned and scanned in turn, the next step's order
 *
 * docs/grid_design.md explains the design. The mpi variant (variants/mpi.c) links these pieces
 * and shares each step's slices out to its ranks (grid_scratch's slice_part, slice_parts).
 */
#ifndef GRID_H
#define GRID_H

#include <float.h>
#include <stdint.h>
#include <string.h>
#if defined(__FMA__) || defined(__AVX__) || defined(__AVX512F__)
#include <immintrin.h>
#endif

#include "../core/sim.h"

/* Most time slices per step. */
#define GRID_K_MAX 4096
/* Widest radix digit: a 2^16-entry histogram. */
#define GRID_RADIX_MAX_BITS 16
/* Cells per box width, `sub` (grid_plan): a cell is 1 / sub of the box of a particle at v_ref,
 * so such a box spans at most sub + 1 cells per axis (docs/grid_design.md, "Binning"); at most
 * GRID_SUB_MAX, so that a reach fits in 2 bits an axis. grid_plan_step chooses it. */
#define GRID_SUB_MAX 3
/* A grid counts as dense, and is counting-sorted, up to this many keys per particle. */
#define GRID_DENSE_CELLS_PER_PARTICLE 8
#define GRID_DENSE_CELLS_MIN 4096
/* Flags of a binned box: how many cells it reaches beyond its corner cell to the right (bits
 * 0-1) and up (bits 2-3), each at most sub; or wide, more than that on an axis. */
#define GRID_EXT_X_MASK 3
#define GRID_EXT_Y_SHIFT 2
#define GRID_WIDE 16
#define GRID_EXT_BITS 4

/* The rounding delta must cover: the pair kernel's type, or double, whichever is coarser (the
 * slice times and the near test are double; the float binning has its own margin, below). */
#if defined(SIM_REAL_F32)
#define GRID_EPS ((double)FLT_EPSILON)
#else
#define GRID_EPS DBL_EPSILON
#endif

/* The float prefilter (docs/grid_design.md, "The slice test"): a run of entries is tested
 * GRID_LANES at a time in float, one vector: 16 lanes (512 bits) where AVX-512 is enabled, 8
 * (256 bits) where AVX is, 4 otherwise (256-bit vectors without AVX make gcc warn of an ABI
 * change). The widest vector pays even where a 512-bit operation executes as two 256-bit
 * halves (Zen 4): half the instructions per pair, and the loop is bound by instructions rather
 * than by the FP units (docs/grid_bound.md has the measurements). The reach is grown by
 * GRID_F32_MARGIN * FLT_EPSILON * B, where B bounds every float it reads (|coordinate| and
 * |displacement| <= B / 2): a generous multiple of the float rounding, which is about
 * 12 FLT_EPSILON B on each end of the relative segment. Below GRID_F32_SPAN_MAX every square
 * of a coordinate is finite; a product that overflows (|p x w|^2 or r2 |w|^2 of a far pair) is
 * +inf, which only ever rejects a far pair or passes one. Above it, the scene gets one slice and
 * one cell, and zeros that pass (the double test decides). */
#ifndef GRID_LANES
#if defined(__AVX512F__)
#define GRID_LANES 16
#elif defined(__AVX__)
#define GRID_LANES 8
#else
#define GRID_LANES 4
#endif
#endif
#if GRID_LANES != 4 && GRID_LANES != 8 && GRID_LANES != 16
#error "GRID_LANES must be 4, 8 or 16"
#endif
#if GRID_LANES == 16 && !defined(__AVX512F__)
#error "GRID_LANES 16 needs AVX-512 (-mavx512f)"
#endif
#define GRID_F32_MARGIN 32
#define GRID_F32_SPAN_MAX 1e18
typedef float grid_vf __attribute__((vector_size(GRID_LANES * sizeof(float))));
typedef int32_t grid_vi __attribute__((vector_size(GRID_LANES * sizeof(int32_t))));

/* Above this N, pairs the prefilter passes wait in the prefetch queue (grid_queue). */
#define GRID_SMALL_N 32768
/* Up to this N a team bins every particle in every band (grid_run_direct): the binning each
 * thread repeats costs less than the barriers and the split into bands on a step that takes
 * about a millisecond, and the scratch of N items a thread is small. */
#define GRID_DIRECT_N 32768
/* From this many threads the team shares out the plan of such a step (three barriers) and each
 * slice's keys (one): at 2 threads one thread's plan and a band's keys of every particle cost
 * less than a barrier that waits for a descheduled thread on a shared machine; on 16 cores the
 * keys of every particle were half of a band's binning (docs/grid_bound.md). */
#define GRID_PLAN_TEAM_MIN 4

/* A particle's state in double, as the world holds it (the decisions are taken in double
 * whatever the build's real type). */
typedef struct grid_particle {
    double x, y, vx, vy;
} grid_particle;

static inline grid_particle grid_part(const sim_world *w, int32_t i)
{
    return (grid_particle){(double)w->x[i], (double)w->y[i], (double)w->vx[i], (double)w->vy[i]};
}

/* The non-wide particles of one slice in cell order, in float (the binning's terms): position
 * at time 0 relative to the grid's corner and displacement over one slice (what the next slice
 * bins), position at this slice's start (what the prefilter reads with the displacement), id.
 * GRID_LANES - 1 more of each, for the prefilter's reads past a run's end. */
typedef struct grid_set {
    float *bx, *by, *ux, *uy, *px, *py;
    int32_t *id;
} grid_set;

/* One thread's scratch, sized for the items it bins (grid_thread_reserve), not for N: on a team
 * every slice is cut into bands of rows, one a thread, so a thread holds about N / T entries
 * (docs/grid_design.md, "Parallel" and "Memory"). */
typedef struct grid_thread {
    grid_set set[2];             /* this slice's entries, and the previous slice's (one thread) */
    int32_t *wide[2];            /* this slice's wide particles, and the previous slice's */
    int32_t *cx0, *cy0, *flag;   /* per input item: corner cell and flags (dense grids: the
                                  * key in cx0); after the sort, the entry each goes to in cy0 */
    int32_t *scell;              /* dense grids: cell of each entry */
    uint8_t *sext;               /* reach bits of each entry */
    int32_t *pos;                /* dense grids: where each key's entries begin */
    uint64_t pos_cap;            /* keys pos can hold */
    uint64_t *ent, *tmp, *skey;  /* sparse grids: radix words, radix buffer, cell of each entry */
    uint32_t *hist;              /* radix histogram */
    int32_t cap;                 /* items the per-item arrays hold (sets: cap + GRID_LANES + 1) */
    int32_t sets;                /* sets allocated to cap: 1 on a team, 2 alone */
    int32_t sink;                /* a slot of the sets no run reads: where the binning puts
                                  * items that are no entry of the slice */
    /* The band split of a team's slice: this thread's part of the source's items, their
     * corner rows (or -1: wide) and base bands. */
    int32_t *prow, *pband;
    int32_t pcap;
    int32_t *bound; /* the bands' first rows, bands + 1 of them (the last is gy) */
    int32_t *cur;   /* where this thread's next item of each band goes in P */
    int32_t *sample; /* rows of GRID_BAND_SAMPLES items a band, for the bands' bounds */
    uint32_t slices; /* slices binned so far in the run (grid_run_direct's lent bands) */
} grid_thread;

#define GRID_COUNT_STRIDE(threads) (2 * (threads) + 1)
/* Items a band whose rows place the bands' bounds (grid_scan.c). */
#define GRID_BAND_SAMPLES 8

/* The team's shared state of a slice cut into bands: the source S (every particle once, in the
 * previous slice's cell order: s->bx, by, ux, uy and s->ord), the items of each band gathered
 * from it (P: base entries and the upper neighbours of the band below), the wide particles,
 * and the counts that place them. */
typedef struct grid_team {
    float *bx, *by, *ux, *uy; /* P */
    int32_t *id;
    int32_t *wide;            /* this slice's wide particles, in thread order */
    int32_t *count;           /* per thread GRID_COUNT_STRIDE(threads): [band][2] items and base
                               * items, then its wide particles */
    struct grid_extent *extent; /* per thread: its particles' extent, for the plan */
    uint32_t *speeds;           /* per thread GRID_SPEED_BINS: its particles' speed counts */
    /* N <= GRID_DIRECT_N on GRID_PLAN_TEAM_MIN threads or more: the slices' whole-grid keys and
     * flags of the plan's floats (grid_whole_keys), two of each, for slices k even and odd. */
    int32_t *whole_key[2], *whole_flag[2];
    struct grid_band_share *share; /* per band: its binned slice, lent to the team's runs */
} grid_team;

typedef struct grid_scratch {
    int32_t n;
    int threads;
    float *bx, *by, *ux, *uy; /* the state in the binning's terms (grid_set), in the order ord:
                               * a team's source S, rewritten in every slice's cell order */
    int32_t *ord, *ord_next; /* particles in the cell order of the last slice of the step before:
                              * the first slice of a step finds them almost sorted */
    double *tk;              /* slice boundaries k / K, k = 0..K */
    grid_thread *th;
    grid_team team;          /* threads > 1 */
    int sub_force; /* 0: grid_plan_step chooses the cells per box width; the tests force 1 to
                    * GRID_SUB_MAX */
    int32_t direct_n; /* a team bins every particle in every band up to this N (GRID_DIRECT_N;
                       * the tests set 0 to run the split into bands on small scenes too) */
    /* The step's slices shared out to slice_parts finders (the mpi variant's ranks, each with
     * a scratch of its own): this one looks at slices slice_part, slice_part + slice_parts, ...
     * (grid_plan's k0, kstep), and K is a multiple of slice_parts where the plan's bounds allow.
     * Dealt in turn rather than in blocks: a slice late in the step costs less (the discs'
     * paths run out of the box, where the binned region thins out), and blocks left the first
     * of two ranks 603 M pair tests to the second's 486 M at N = 2 10^5 (in turn: 558 M and
     * 532 M). Each candidate is pushed from one slice, so the parts' candidates together are the
     * whole finder's. slice_parts 1 (grid_scratch_create): every slice. */
    int slice_part, slice_parts;
} grid_scratch;

/* What one step's binning uses. */
typedef struct grid_plan {
    int K;
    int k0, kstep;    /* the slices this finder looks at, k0, k0 + kstep, ... < K: all (0, 1), or
                       * its share (grid_scratch's slice_parts) */
    int bands;        /* > 1: every slice is cut into this many bands of rows, one a thread */
    int32_t gx, gy;   /* cells per axis */
    double x0, y0;    /* the grid's lower-left corner: the origin of the binning's floats */
    float inv_h;      /* 1 / cell size; 0 puts everything in one cell */
    float topx, topy; /* the last column and row */
    float rpad;       /* how far a box reaches beyond the centre's path (r, delta, margin) */
    double reach2;    /* (2r + delta)^2: centres closer than this in a slice are near */
    float freach2;    /* the prefilter's reach squared (2r, delta, margin), rounded up */
    int32_t sub;      /* cells per box width at v_ref (1 .. GRID_SUB_MAX) */
    float fend;       /* the prefilter's end slack: its reach times the longest relative
                       * displacement in a slice, rounded up (near_f32) */
    int f32_off;      /* magnitudes floats cannot carry: one slice, one cell, zeros that pass */
    int pbits;        /* bits of an item index in a radix word */
} grid_plan;

/* What a slice reads: items [0, m) from arrays (ids: id[e], or e itself when id is NULL), then
 * items [m, m + nwide) are the particles wide[] (read from the scratch's particle array). */
typedef struct grid_src {
    const float *bx, *by, *ux, *uy;
    const int32_t *id;
    int32_t m;
    const int32_t *wide;
    int32_t nwide;
    /* Or NULL: items [0, m)'s keys in the whole grid's numbering and their flags, computed by
     * the team once (grid_whole_keys), from which a dense band takes its own. */
    const int32_t *whole_key, *whole_flag;
} grid_src;

/* One band of one binned slice. Cells are numbered row-major with stride spanx from (row0,
 * column -sub), so that every cell a run reaches has a number; the band's base cells are
 * [0, base_end), and the sub rows above it (from row1) take part as upper neighbours. */
typedef struct grid_bins {
    int dense;         /* counting-sorted: th->pos and th->scell; else th->skey */
    int32_t ne, nw;    /* entries (base rows and the row above), wide particles */
    int32_t nbase;     /* entries whose base cell is in the band: the first nbase */
    int32_t below;     /* items below the band's rows, not wide: where the source is every
                        * particle, the base entries of the bands below */
    int32_t row0, row1;
    int32_t rowlast;   /* the last row whose entries are binned: row1 + sub - 1, clipped */
    int32_t sub;       /* cells per box width (grid_plan) */
    int32_t kshift;    /* dense: 2^kshift keys a cell, one for each reach 0 .. sub */
    uint64_t spanx;    /* cells per numbered row: columns + 2 sub + 1 */
    uint64_t ncell;    /* cells numbered */
    uint64_t base_end; /* the first cell number above the band's base rows */
} grid_bins;

/* A band of a team's slice, lent to every thread: once its owner has binned slice
 * `ready` (a count of the run's slices) into its set, any thread claims chunks of
 * GRID_RUN_CHUNK of its base entries from `next` and looks at their runs. Each on cache lines
 * of its own. */
typedef struct grid_band_share {
    _Alignas(64) grid_bins b;
    int32_t next;
    uint32_t ready;
} grid_band_share;
/* Base entries a claim takes. */
#define GRID_RUN_CHUNK 32

/* Pairs the prefilter passed wait in a ring of GRID_QUEUE while their particles' double state
 * (s->part) and the kernel's inputs (the world's arrays) are prefetched: at N = 10^6 these are
 * reads anywhere in 32 MB + 32 MB, and pair_found, which took each miss in turn, was 22% of the
 * finder's samples (perf, one thread, `1000000 200000 1 2`). */
#define GRID_QUEUE 16
typedef struct grid_queue {
    int32_t a[GRID_QUEUE], b[GRID_QUEUE];
    /* The len <= GRID_QUEUE waiting pairs end at slot at - 1 (mod GRID_QUEUE). No count of
     * all the pairs a slice passed: on one slice of N >= 92,682 particles (f32_off scenes) a
     * 32-bit one would wrap and lose the pairs queued then. */
    int at, len;
    int on;     /* N > GRID_SMALL_N: where the state is in cache (the report benchmark) the
                 * queue cost 6% of the finder's time */
} grid_queue;

/* What the finder knows while it looks at the pairs of slice k. */
typedef struct grid_ctx {
    const sim_world *w;
    const grid_scratch *s;
    const grid_plan *g;
    int k;
    sim_cand_buf *buf;
    grid_queue *queue; /* pairs passed by the prefilter, not yet decided */
} grid_ctx;

/* One particle looked at against runs of entries: its prefilter floats and its id. */
typedef struct grid_probe {
    float x, y, wx, wy;
    int32_t id;
} grid_probe;

/* ---- grid_finder.c ---- */

/* The finder (sim_variant's find_pairs): the step's plan, then its slices (all, or the share
 * slice_part of slice_parts) alone or on the team, pairs into the sink's buffers. */
void grid_find_pairs(const sim_world *w, sim_pair_sink *sink);

/* ---- grid_state.c ---- */

/* The finder's per-run memory for a world of w->n particles and `threads` threads: O(N) shared,
 * and per thread what its bands need, grown on demand (sim_variant's scratch_create); NULL
 * when memory is short. */
void *grid_scratch_create(const sim_world *w, int threads);
void grid_scratch_destroy(void *scratch);
/* Room in th's per-item arrays for `items` items (`sets` sets: 1 or 2), and in its band
 * split for `part` source items. Returns 0, or -1 when memory is short. */
int grid_thread_reserve(grid_thread *th, int32_t items, int sets);
int grid_thread_reserve_part(grid_thread *th, int32_t part);
/* Room for `keys` + 2 dense keys (-1 when memory is short). */
int grid_thread_reserve_keys(grid_thread *th, uint64_t keys);

/* ---- grid_plan.c ---- */

/* Bits needed to hold values < v (v >= 1). */
int grid_bits_for(uint64_t v);
/* The plan of this step for the world's state (and s's bx, by, ux, uy, tk filled in the plan's
 * terms), for `threads` threads and s's cells (sub_force) and share of the slices: the pieces
 * below, one after the other. */
void grid_plan_step(const sim_world *w, grid_scratch *s, grid_plan *g, int threads);
/* The pieces, so that a team shares the loops over particles out: the extent of particles
 * [i0, i1) and its merge with another's (min and max: any order gives the same); whether the
 * plan needs the speeds' histogram, and the counts of particles [i0, i1) in it (added to
 * count, GRID_SPEED_BINS of them, zeroed by the caller); the plan from those; the binning's
 * floats of entries [e0, e1) of s->ord; the slices' times. */
typedef struct grid_extent {
    double minx, maxx, miny, maxy, vmax;
} grid_extent;
/* Bins of the speed histogram that picks v_ref. */
#define GRID_SPEED_BINS 1024
void grid_extent_of(const sim_world *w, int32_t i0, int32_t i1, grid_extent *e);
void grid_extent_merge(grid_extent *a, const grid_extent *b);
int grid_speeds_needed(const sim_world *w, const grid_extent *e);
void grid_speed_count(const sim_world *w, int32_t i0, int32_t i1, double vmax, uint32_t *count);
void grid_plan_make(const sim_world *w, const grid_extent *e, const uint32_t *count,
                    const grid_scratch *s, grid_plan *g, int threads);
void grid_plan_floats(const sim_world *w, grid_scratch *s, const grid_plan *g, int32_t e0,
                      int32_t e1);
void grid_plan_times(grid_scratch *s, const grid_plan *g);

/* ---- grid_binning.c ---- */

/* The first of the n sorted keys that is >= v. */
int32_t grid_lower_bound(const uint64_t *key, int32_t n, uint64_t v);
/* Whether the dense keys of the whole grid (rows 0 .. gy - 1 as one band) fit an int32_t. */
int grid_whole_keys_fit(const grid_plan *g);
/* The dense keys (and flags) of the source's items [e0, e1) in slice kf, numbered over the whole
 * grid as one band: whole_key[e], whole_flag[e]. */
void grid_whole_keys(const grid_src *src, int32_t e0, int32_t e1, const grid_plan *g, float kf,
                     int32_t *restrict whole_key, int32_t *restrict whole_flag);
/* Bin slice kf, the band of rows [row0, row1), from src into dst / wide; *b describes the
 * result. Returns 0, or -1 when memory is short. */
int grid_bin_slice(const grid_src *src, const sim_world *w, const grid_plan *g, float kf,
                   int32_t row0, int32_t row1, grid_thread *th, grid_set *dst, int32_t *wide,
                   grid_bins *b);

/* ---- grid_prefilter.c ---- */

/* Pair (a, b) passed the prefilter: queue it, and decide the one queued GRID_QUEUE pairs ago.
 * The decisions and pushes of a slice are those of deciding at once, in the same order. Out of
 * line: inlined into the prefilter's loop, it slowed that loop at N = 10^4 by 12%. */
void grid_pair_passed(const grid_ctx *cx, int32_t a, int32_t b);
/* Decide every pair still queued (at the end of a slice). */
void grid_queue_flush(const grid_ctx *cx);

/* ---- grid_runs.c ---- */

/* The runs of a binned slice's band, dense or sparse grids (dense: of its base entries
 * [a0, a1) only); the wide boxes against the band's entries, and against each other. Each
 * returns the pairs looked at. */
uint64_t grid_runs_dense(const grid_ctx *cx, const grid_thread *th, const grid_set *z,
                         const grid_bins *b, int32_t a0, int32_t a1);
uint64_t grid_runs_sparse(const grid_ctx *cx, const grid_thread *th, const grid_set *z,
                          const grid_bins *b);
uint64_t grid_runs_wide(const grid_ctx *cx, const grid_thread *th, const grid_set *z,
                        const int32_t *wide, const grid_bins *b);
/* Rows m = first, first + stride, ... of the wide boxes' pairs (m, q > m), so that the bands
 * of a team share them. */
uint64_t grid_wide_pairs(const grid_ctx *cx, const int32_t *wide, int32_t nw, int first,
                         int stride);

/* ---- grid_scan.c ---- */

/* Each of these works through the plan's slices k0, k0 + kstep, ... < K (every slice of the
 * step, or this finder's share) and leaves the particles in the cell order of the last one in
 * s->ord_next
 * (where the share is empty, in s->ord's order).
 * One thread alone: every slice, each binned from the one before; pairs into buf. */
void grid_run_alone(const sim_world *w, grid_scratch *s, const grid_plan *g, sim_cand_buf *buf);
/* Thread `me` of a team of `team` (inside a parallel region, every thread calls it): every
 * slice of the step cut into g->bands bands of rows, a band a thread. Returns 0, or -1 when
 * memory ran short (buf is then marked failed). */
void grid_run_team(const sim_world *w, grid_scratch *s, const grid_plan *g, int me, int team,
                   sim_cand_buf *buf);
/* Thread `me` of a team on a small scene (N <= GRID_DIRECT_N): a band of rows a thread, each
 * binned from every particle (the plan's floats); scratch for N items a thread. Below
 * GRID_PLAN_TEAM_MIN threads no barrier between slices; from it (where the team's key arrays
 * are) each thread first computes the slice's keys of N / T particles, and a barrier later
 * every band takes its own from them. Times its own busy seconds (barriers left out). */
void grid_run_direct(const sim_world *w, grid_scratch *s, const grid_plan *g, int me, int team,
                     sim_cand_buf *buf);

/* ==== Inline helpers ====
 *
 * The functions below are called inside the hottest loops of the other pieces: the geometry in
 * the binning's vectorised loops (per particle and slice) and in the runs, the run scan per
 * probe. Defined here, every piece's loops inline them; as functions of a piece of their own
 * the finder took 1.78x as long on the report benchmark (1.12x with -flto), and the run scan
 * alone out of line 1.05-1.09x (docs/grid_bound.md, "The pieces as C files"). */

/* ---- The geometry: one function per decision, so that the binning, the prefilter and the
 * double decision agree by construction ---- */

/* A particle in the binning's terms (grid_set): position at time 0 relative to the grid's
 * corner, displacement over one slice of 1/K step; zeros when floats cannot carry the scene. */
static inline void particle_f32(const grid_particle *q, const grid_plan *g, float *bx, float *by,
                                float *ux, float *uy)
{
    const int off = g->f32_off;
    *bx = off ? 0 : (float)(q->x - g->x0), *by = off ? 0 : (float)(q->y - g->y0);
    *ux = off ? 0 : (float)(q->vx / g->K), *uy = off ? 0 : (float)(q->vy / g->K);
}

/* Position at the start of slice k (k as a float). */
static inline float slice_start(float b, float u, float k)
{
    return b + k * u;
}

/* The cell of coordinate v: floor(v / h) clamped to [0, top]. Monotone in v, so boxes that
 * overlap have cell ranges that intersect. */
static inline int32_t cell_of(float v, float inv_h, float top)
{
    float c = v * inv_h;
    c = c > 0 ? c : 0;
    c = c < top ? c : top;
    return (int32_t)c;
}

/* The cells of the box a centre sweeps in a slice from p to p + u, grown by rpad: [*a, *b]. */
static inline void axis_cells(float p, float u, float rpad, float inv_h, float top, int32_t *a,
                              int32_t *b)
{
    const float q = p + u;
    /* min and max written so that the compiler turns them into vector min/max. */
    *a = cell_of((p < q ? p : q) - rpad, inv_h, top);
    *b = cell_of((q < p ? p : q) + rpad, inv_h, top);
}

/* Corner cell and flags of the box from slice-start position (px, py), displacement (ux, uy). */
static inline void box_cells(float px, float py, float ux, float uy, const grid_plan *g,
                             int32_t *cx, int32_t *cy, int32_t *flag)
{
    int32_t a, b, c, d;
    axis_cells(px, ux, g->rpad, g->inv_h, g->topx, &a, &b);
    axis_cells(py, uy, g->rpad, g->inv_h, g->topy, &c, &d);
    *cx = a;
    *cy = c;
    /* Without a branch, so that slice_keys' loop vectorises: a wide box's reach is clipped
     * (and never read). */
    const int32_t ex = b - a, ey = d - c, s = g->sub;
    const int32_t exc = ex < s ? ex : s, eyc = ey < s ? ey : s;
    *flag = exc | eyc << GRID_EXT_Y_SHIFT | ((ex > s) | (ey > s)) * GRID_WIDE;
}

/* Do centres at relative position (dx, dy) and velocity (ddx, ddy) at time 0 come within
 * sqrt(reach2) of each other at some time in [t0, t1]? The closest point of the relative
 * segment; dd == 0 gives NaN or an infinity, which the clamps turn into t0 or t1. Symmetric:
 * swapping the particles negates dx..ddy exactly and changes no rounding. A long, so that a
 * vectorised loop keeps 64-bit lanes. */
static inline long near_in_slice(double dx, double dy, double ddx, double ddy, double t0,
                                 double t1, double reach2)
{
    const double dd = ddx * ddx + ddy * ddy;
    double s = -(dx * ddx + dy * ddy) / dd;
    s = s > t0 ? s : t0;
    s = s < t1 ? s : t1;
    const double px = dx + s * ddx, py = dy + s * ddy;
    return px * px + py * py <= reach2;
}

/* Is slice k in the set S of the pair (i, j)? */
static inline long near_pair(const sim_world *w, const double *restrict tk, double reach2,
                             int32_t i, int32_t j, int k)
{
    const grid_particle a = grid_part(w, i), b = grid_part(w, j);
    return near_in_slice(b.x - a.x, b.y - a.y, b.vx - a.vx, b.vy - a.vy, tk[k], tk[k + 1],
                         reach2);
}

/* a * b + c, rounded once where the machine has FMA. Only the float prefilter uses it: its
 * error bound (below) holds for a rounding of a * b and of the sum as well as for one rounding,
 * and it decides no output (the exact builds' rule, -ffp-contract=off, is for the double
 * arithmetic that does). It saves 2-3% of the finder on the report benchmark. */
static inline grid_vf vf_fma(grid_vf a, grid_vf b, grid_vf c)
{
#if GRID_LANES == 16
    return (grid_vf)_mm512_fmadd_ps((__m512)a, (__m512)b, (__m512)c);
#elif GRID_LANES == 8 && defined(__FMA__)
    return (grid_vf)_mm256_fmadd_ps((__m256)a, (__m256)b, (__m256)c);
#elif GRID_LANES == 4 && defined(__FMA__)
    return (grid_vf)_mm_fmadd_ps((__m128)a, (__m128)b, (__m128)c);
#else
    return a * b + c;
#endif
}

/* The prefilter's comparisons, lane by lane, and their result as bits (lane l is bit l). With
 * AVX-512 a comparison writes a mask register, and the lanes stay there to the end: written
 * with the vector extension's operators, gcc turned the mask into a vector of -1 / 0 and back
 * (a vmovdqa32 and a vptestmd a vector). */
#if GRID_LANES == 16
typedef __mmask16 grid_vm;
static inline grid_vm vf_le(grid_vf a, grid_vf b)
{
    return _mm512_cmp_ps_mask((__m512)a, (__m512)b, _CMP_LE_OQ);
}
static inline grid_vm vf_gt(grid_vf a, grid_vf b)
{
    return _mm512_cmp_ps_mask((__m512)a, (__m512)b, _CMP_GT_OQ);
}
static inline grid_vm vf_ge(grid_vf a, grid_vf b)
{
    return _mm512_cmp_ps_mask((__m512)a, (__m512)b, _CMP_GE_OQ);
}
static inline uint32_t vm_bits(grid_vm m)
{
    return m;
}
#else
typedef grid_vi grid_vm;
static inline grid_vm vf_le(grid_vf a, grid_vf b)
{
    return a <= b;
}
static inline grid_vm vf_gt(grid_vf a, grid_vf b)
{
    return a > b;
}
static inline grid_vm vf_ge(grid_vf a, grid_vf b)
{
    return a >= b;
}
static inline uint32_t vm_bits(grid_vm m)
{
#if GRID_LANES == 8 && defined(__AVX__)
    return (uint32_t)_mm256_movemask_ps((__m256)m);
#else
    uint32_t r = 0;
    for (int l = 0; l < GRID_LANES; l++)
        r |= (uint32_t)(m[l] != 0) << l;
    return r;
#endif
}
#endif

/* Every lane x. */
static inline grid_vf vf_splat(float x)
{
    const grid_vf zero = {0};
    return zero + x;
}

/* The prefilter, GRID_LANES pairs at once: may the relative segments from p to p + w come
 * within R = sqrt(r2) of the origin? It passes every pair that does (and some that do not; the
 * double test decides): p itself within reach, or the line within reach (|p x w|^2 <= r2 |w|^2,
 * no division) with the closest point no further than R beyond either end along w (p.w <= R |w|
 * and (p + w).w >= -R |w|). The two ends are tested against R |w| bounded over the slice,
 * `tend`, R times the longest |w|, instead of |w| itself: a pair whose closest point is the far
 * end q = p + w has q.w >= -|q| |w| >= -R |w| >= -tend, so it passes without q's own distance
 * being computed (2 multiplications and 3 additions fewer a vector: 4% of the finder on the
 * report benchmark). Rounding: the cross product loses about FLT_EPSILON |p| |w| to it, and
 * q.w = p.w + |w|^2 a few FLT_EPSILON (|p| + |w|) |w|; the margin in R and in tend covers
 * both. Lane l of the result is bit l.
 *
 * near_f32_line is the line test alone. A pair whose closest point is its start p, |p| <= R,
 * passes it too (|p x w| <= |p| |w| <= R |w|, and -R |w| <= p.w <= R |w| <= tend), and so does
 * every pair with w == 0 (all three sides are 0 then). near_f32 adds p's own distance and leaves
 * pairs with w == 0 to it (`ww > 0`): equal displacements would otherwise pass whatever their
 * distance. The runs test near_f32_line, which has 2 multiplications and a comparison fewer, and
 * near_f32 only on a chunk where a lane passed it (at most 1.7% of the chunks on the report
 * benchmark): the finder takes 0.91x the time of near_f32 on every chunk there, and a scene
 * whose displacements are all equal, where every lane passes the line test, pays near_f32 on its
 * chunks rather than a double test on every pair. */
static inline grid_vm near_line(grid_vf px, grid_vf py, grid_vf wx, grid_vf wy, float r2,
                                float tend)
{
    const grid_vf cr = vf_fma(px, wy, -(py * wx));
    const grid_vf ww = vf_fma(wx, wx, wy * wy), pw = vf_fma(px, wx, py * wy);
    return vf_le(pw, vf_splat(tend)) & vf_ge(pw + ww, vf_splat(-tend)) &
           vf_le(cr * cr, r2 * ww);
}

static inline uint32_t near_f32_line(grid_vf px, grid_vf py, grid_vf wx, grid_vf wy, float r2,
                                     float tend)
{
    return vm_bits(near_line(px, py, wx, wy, r2, tend));
}

static inline uint32_t near_f32(grid_vf px, grid_vf py, grid_vf wx, grid_vf wy, float r2,
                                float tend)
{
    const grid_vf zero = {0};
    return vm_bits(vf_le(vf_fma(px, px, py * py), vf_splat(r2)) |
                   (vf_gt(vf_fma(wx, wx, wy * wy), zero) & near_line(px, py, wx, wy, r2, tend)));
}

/* Dense grids: 2^keys_shift(sub) keys a cell, one for each reach to the right, 0 .. sub (two
 * for whole-box cells, four for any subdivision). */
static inline int32_t keys_shift(int32_t sub)
{
    return sub > 1 ? 2 : 1;
}

/* ---- The prefilter's scan of a run (the pairs it passes go to grid_pair_passed) ---- */

/* The chunk of entries [b, b + GRID_LANES) of z against probe a: relative position and
 * displacement, lane by lane. */
typedef struct grid_chunk {
    grid_vf px, py, wx, wy;
} grid_chunk;

static inline grid_chunk chunk_of(const grid_set *z, int32_t b, const grid_probe *a)
{
    grid_vf X, Y, WX, WY;
    memcpy(&X, z->px + b, sizeof X), memcpy(&Y, z->py + b, sizeof Y);
    memcpy(&WX, z->ux + b, sizeof WX), memcpy(&WY, z->uy + b, sizeof WY);
    return (grid_chunk){X - a->x, Y - a->y, WX - a->wx, WY - a->wy};
}

/* The prefilter over the run [lo, hi) of z against probe a: every pair it passes goes to
 * grid_pair_passed, in entry order. Reads up to GRID_LANES - 1 entries past the run's end. One
 * pass, a branch a chunk that is rarely taken: the lanes are a mask, the chunk's passed pairs
 * its set bits, near_f32_line on every chunk and near_f32 on those where a lane passed it
 * (above). The single pass took 0.91x the finder's time of two, an OR of every chunk's lanes as
 * a vector and the chunks again where any was set (report benchmark); keeping the lanes in mask
 * registers to the end 0.96x more. The rare path out of line took 1.08x (a noinline function:
 * gcc then kept the run's pointers and the chunk in memory) and 1.3x (an inner loop without the
 * call, left at the first lane passed). */
static inline void scan_run(const grid_ctx *cx, const grid_set *z, int32_t lo, int32_t hi,
                            const grid_probe *a, float r2, float tend)
{
    /* A local copy: grid_pair_passed's stores could change *z, which made gcc reload its pointers
     * on every chunk. */
    const grid_set zl = *z;
    for (int32_t b = lo; b < hi; b += GRID_LANES) {
        const grid_chunk q = chunk_of(&zl, b, a);
        uint32_t hit = near_f32_line(q.px, q.py, q.wx, q.wy, r2, tend);
        if (__builtin_expect(hit != 0, 0)) {
            hit &= near_f32(q.px, q.py, q.wx, q.wy, r2, tend);
            /* Lanes past the run's end: entries of the slice or the zeroed padding. */
            if (hi - b < GRID_LANES)
                hit &= (1u << (hi - b)) - 1;
            for (; hit; hit &= hit - 1)
                grid_pair_passed(cx, a->id, zl.id[b + __builtin_ctz(hit)]);
        }
    }
}

/* The prefilter over two runs of entries of z, [lo1, hi1) and [lo2, hi2) (either may be
 * empty), against probe a. Returns the pairs looked at. */
static inline int32_t run_prefilter(const grid_ctx *cx, const grid_set *z, int32_t lo1,
                                    int32_t hi1, int32_t lo2, int32_t hi2, const grid_probe *a)
{
    const float r2 = cx->g->freach2, tend = cx->g->fend;
    scan_run(cx, z, lo1, hi1, a, r2, tend);
    scan_run(cx, z, lo2, hi2, a, r2, tend);
    return (hi1 > lo1 ? hi1 - lo1 : 0) + (hi2 > lo2 ? hi2 - lo2 : 0);
}

#endif /* GRID_H */
