/*
 * grid_state.h: the grid finder's shared constants, its per-run and per-thread state, and the
 * memory of both (allocated once per run by scratch_create, O(N) per thread). Included once,
 * by variants/grid.c, before the other grid_*.h pieces; docs/grid_design.md explains the design.
 */
#ifndef GRID_STATE_H
#define GRID_STATE_H

#include <float.h>
#include <stdint.h>
#include <stdlib.h>

#include "../core/sim.h"

/* Most time slices per step. */
#define GRID_K_MAX 4096
/* Widest radix digit: a 2^16-entry histogram. */
#define GRID_RADIX_MAX_BITS 16
/* Cells per box width, `sub` (grid_plan): a cell is 1 / sub of the box of a particle at v_ref,
 * so such a box spans at most sub + 1 cells per axis (docs/grid_design.md, "Binning"); at most
 * GRID_SUB_MAX, so that a reach fits in 2 bits an axis. grid_params.h chooses it. */
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
 * change). On Zen 3, 8 lanes took 15% less of the finder's time than 4 (report benchmark, 21
 * interleaved runs); on Zen 4 (AMD EPYC, znver4), which executes a 512-bit operation as two
 * 256-bit halves, 16 lanes took 9.6% less than 8 (medians of 9 interleaved runs, 2026-11-25):
 * half the instructions per pair, where the loop is bound by instructions rather than by the
 * FP units. The reach is grown by GRID_F32_MARGIN * FLT_EPSILON * B, where B bounds every float
 * it reads (|coordinate| and |displacement| <= B / 2): a generous multiple of the float
 * rounding, which is about 12 FLT_EPSILON B on each end of the relative segment. Below
 * GRID_F32_SPAN_MAX every square of a coordinate is finite; a product that overflows (|p x w|^2
 * or r2 |w|^2 of a far pair) is +inf, which only ever rejects a far pair or passes one. Above
 * it, the scene gets one slice and one cell, and zeros that pass (the double test decides). */
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

/* A particle's state in double, for gathers by index. */
typedef struct grid_particle {
    double x, y, vx, vy;
} grid_particle;

/* The non-wide particles of one slice in cell order, in float (the binning's terms): position
 * at time 0 relative to the grid's corner and displacement over one slice (what the next slice
 * bins), position at this slice's start (what the prefilter reads with the displacement), id.
 * GRID_LANES - 1 more of each, for the prefilter's reads past a run's end. */
typedef struct grid_set {
    float *bx, *by, *ux, *uy, *px, *py;
    int32_t *id;
} grid_set;

/* One thread's scratch, every array sized for N. */
typedef struct grid_thread {
    grid_set set[2];             /* this slice's entries, and the previous slice's */
    int32_t *wide[2];            /* this slice's wide particles, and the previous slice's */
    int32_t *cx0, *cy0, *flag;   /* per input item: corner cell and flags (dense grids: the
                                  * key in cx0); after the sort, the entry each goes to in cy0 */
    int32_t *scell;              /* dense grids: cell of each entry */
    uint8_t *sext;               /* reach bits of each entry */
    int32_t *pos;                /* dense grids: where each key's entries begin */
    uint64_t pos_cap;            /* keys pos can hold (2^kshift a cell, grid_bins) */
    uint64_t *ent, *tmp, *skey;  /* sparse grids: radix words, radix buffer, cell of each entry */
    uint32_t *hist;              /* radix histogram */
    int32_t sink;                /* a slot of the sets no run reads: where the binning puts
                                  * items that are no entry of the slice */
} grid_thread;

typedef struct grid_scratch {
    int32_t n;
    int threads;
    float *bx, *by, *ux, *uy; /* the state in the binning's terms (grid_set), in the order ord */
    int32_t *ord, *ord_next; /* particles in the cell order of the last slice of the step before:
                              * the first slice of a step finds them almost sorted */
    grid_particle *part;     /* the state in double, by particle, for gathers */
    double *tk;              /* slice boundaries k / K, k = 0..K */
    grid_thread *th;
    int sub_force; /* 0: plan_step chooses the cells per box width; tests set 1 .. GRID_SUB_MAX */
} grid_scratch;

/* What one step's binning uses. */
typedef struct grid_plan {
    int K;
    int bands;        /* > 1: items are (slice, band of rows) */
    int blocks;       /* bands == 1: items are blocks of consecutive slices */
    int32_t band_rows;
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

/* ---- memory ---- */

static void thread_free(grid_thread *t)
{
    for (int b = 0; b < 2; b++) {
        free(t->set[b].bx), free(t->set[b].by), free(t->set[b].ux), free(t->set[b].uy);
        free(t->set[b].px), free(t->set[b].py);
        free(t->set[b].id), free(t->wide[b]);
    }
    free(t->cx0), free(t->cy0), free(t->flag), free(t->scell), free(t->sext), free(t->pos);
    free(t->ent), free(t->tmp), free(t->skey), free(t->hist);
}

static void scratch_destroy(void *p)
{
    grid_scratch *s = p;
    if (!s)
        return;
    if (s->th)
        for (int k = 0; k < s->threads; k++)
            thread_free(&s->th[k]);
    free(s->th);
    free(s->bx), free(s->by), free(s->ux), free(s->uy), free(s->part), free(s->tk);
    free(s->ord), free(s->ord_next);
    free(s);
}

static int thread_alloc(grid_thread *t, size_t n)
{
    const size_t i = n * sizeof(int32_t), u = n * sizeof(uint64_t), f = n + GRID_LANES;
    int ok = 1;
    for (int b = 0; b < 2; b++) {
        grid_set *z = &t->set[b];
        /* Zeroed: the lanes read past the last entry are always finite. */
        z->bx = calloc(f, sizeof(float)), z->by = calloc(f, sizeof(float));
        z->ux = calloc(f, sizeof(float)), z->uy = calloc(f, sizeof(float));
        z->px = calloc(f, sizeof(float)), z->py = calloc(f, sizeof(float));
        z->id = calloc(f, sizeof(int32_t)), t->wide[b] = malloc(i);
        ok &= z->bx && z->by && z->ux && z->uy && z->px && z->py && z->id && t->wide[b];
    }
    /* The last slot, n + GRID_LANES - 1 = N + GRID_LANES: a slice has at most N entries, and
     * the prefilter reads at most GRID_LANES - 1 slots past the last. */
    t->sink = (int32_t)(f - 1);
    t->cx0 = malloc(i), t->cy0 = malloc(i), t->flag = malloc(i), t->scell = malloc(i);
    t->sext = malloc(n);
    t->pos_cap = GRID_DENSE_CELLS_PER_PARTICLE * (uint64_t)n + GRID_DENSE_CELLS_MIN;
    t->pos = malloc((size_t)(t->pos_cap + 2) * sizeof(int32_t));
    t->ent = malloc(u), t->tmp = malloc(u), t->skey = malloc(u);
    t->hist = malloc(((size_t)1 << GRID_RADIX_MAX_BITS) * sizeof(uint32_t));
    ok &= t->cx0 && t->cy0 && t->flag && t->scell && t->sext && t->pos && t->ent && t->tmp &&
          t->skey && t->hist;
    return ok ? 0 : -1;
}

static void *scratch_create(const sim_world *w, int threads)
{
    grid_scratch *s = calloc(1, sizeof *s);
    if (!s)
        return NULL;
    const size_t n = (size_t)w->n + 1;
    s->n = w->n;
    s->threads = threads;
    s->bx = malloc(n * sizeof(float)), s->by = malloc(n * sizeof(float));
    s->ux = malloc(n * sizeof(float)), s->uy = malloc(n * sizeof(float));
    s->part = malloc(n * sizeof *s->part);
    s->ord = malloc(n * sizeof(int32_t)), s->ord_next = malloc(n * sizeof(int32_t));
    s->tk = malloc((GRID_K_MAX + 1) * sizeof(double));
    s->th = calloc((size_t)threads, sizeof *s->th);
    if (!s->bx || !s->by || !s->ux || !s->uy || !s->part || !s->ord || !s->ord_next || !s->tk ||
        !s->th) {
        scratch_destroy(s);
        return NULL;
    }
    for (int32_t i = 0; i < w->n; i++)
        s->ord[i] = i;
    for (int k = 0; k < threads; k++)
        if (thread_alloc(&s->th[k], n)) {
            scratch_destroy(s);
            return NULL;
        }
    return s;
}

#endif /* GRID_STATE_H */
