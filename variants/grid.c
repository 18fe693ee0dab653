/*
 * grid: a space-time broad phase. Only pairs that can meet within the step are tested, with
 * the shared kernel (sim_pair_time), so the candidates, and the output, are those of seq, for
 * every input and thread count.
 *
 * Why time as well as space: in the report's scenes a particle moves L/8 to L/4 per step, so
 * the boxes swept over a whole step overlap for a large fraction of all pairs. The step is cut
 * into K time slices [k/K, (k+1)/K]; in each, a particle's box is the box its disc sweeps in
 * that slice, padded (below). Boxes are binned into a uniform grid of
 * cell size h, the box width of a particle at the reference speed v_ref, so such a box spans at
 * most 2 cells per axis. K = GRID_K_FACTOR * v_ref * sqrt(N) / L (at least 1, at most
 * v_ref / 2r): it balances the N*K binning work against the pair checks, which fall as 1/K
 * (factor 0.2 measured best of 0.2-0.35 on the report benchmark, and of 0.2 and 0.3 at
 * N = 10^6, where it took 40 s against 46 s).
 *
 * In float: the binning and the prefilter (below) work on floats relative to the grid's corner
 * (position at time 0, displacement per slice, position at the slice's start), half the bytes
 * of doubles and twice the lanes of a vector. Every float is within a few FLT_EPSILON * bound
 * of its exact value (bound: twice the largest coordinate or displacement), and the boxes and
 * the prefilter's reach are padded by GRID_F32_MARGIN times that, so near (in double) in a
 * slice implies that the float boxes overlap and that the prefilter passes. Only the decisions
 * (near, sim_pair_time) are taken in double, on the particles' own state. Scenes whose bound
 * floats cannot square (about 1e18) get one slice and one cell, every pair looked at.
 *
 * Binning ("lo corner"): a box whose cell range is at most 2x2 is entered once, in the cell of
 * its lower-left corner, with two bits saying whether it reaches into the next column / row.
 * Two boxes whose cell ranges intersect then have corner cells at most one apart, and each such
 * pair is looked at exactly once per slice: within a cell, and towards the right, upper,
 * upper-right and upper-left neighbour cells (of the upper-left one only the entries reaching
 * its next column: within a cell those come last, so every neighbourhood is two runs of
 * consecutive entries). Boxes wider than 2 cells on an axis (particles faster than v_ref, a
 * 1/128 quantile of the speeds, so few) are "wide": looked at against the corner cells their
 * range can reach, and against each other, once per slice.
 *
 * Cell order: a counting sort into per-cell starts when the grid is dense (cells not much more
 * than particles), else an LSD radix sort of (cell, reach bits, index) words: deterministic, and
 * O(N) memory whatever L is (a huge sparse grid only costs more radix passes). A thread works
 * through a block of consecutive slices; each slice starts from the previous slice's sorted
 * entries, which a particle leaves by at most one cell per axis, so every pass over memory is
 * nearly sequential (for N = 10^6 that halved the time); and a step starts from the order of
 * the step before's last slice.
 *
 * The slice test: a pair looked at in slice k goes on only if the centres come within
 * 2r + delta of each other during [k/K, (k+1)/K] (closest point of the relative segment, in
 * double; the float prefilter, four pairs a vector, over the runs of candidates first). "Near in
 * slice k" is one function of the pair and k, so the set S of slices where it holds is well
 * defined, and near in k implies that the float boxes overlap in k, hence that the pair is
 * looked at in k.
 *
 * Exactly once: a near pair is tested with sim_pair_time; an accepted pair with time t is pushed
 * from the slice kt = min(K-1, floor(t*K)) when kt is in S, else (rounding in a degenerate,
 * near-tangent pair can put t where the discs are not near) from the first slice of S. Every
 * slice evaluates "kt in S" and "an earlier slice in S" with the same function, so they agree.
 *
 * Never missed: if sim_pair_time accepts a pair, the discs come within 2r (up to its rounding,
 * orders of magnitude below delta = 4 sqrt(eps) (L + 2 vmax + 4r)) at some time in [0, 1], so
 * the pair is near in that time's slice, so S is not empty. Cells are a monotone function of
 * the coordinate (floor of a scaled float, clamped to the grid: a particle outside the grid's
 * region lands in its border cells), so overlapping boxes have intersecting cell ranges.
 *
 * Parallel: threads take work items dynamically, each with its own scratch and candidate buffer;
 * an item is one slice (N <= GRID_SMALL_N; K is then rounded up to a multiple of the thread
 * count), a block of consecutive slices (larger N; one thread: all K), or, when slices are
 * fewer than threads
 * (slow scenes: K = 1), one slice restricted to a band of cell rows; a pair is looked at in
 * the band of its base cell only. The candidates found do not depend on K, bands or blocks,
 * and the core sorts them, so neither the thread count nor the order of finding matters.
 *
 * Memory: O(N) per thread, allocated once per run (scratch_create).
 */
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include <omp.h>

#include "core/sim.h"

/* Most time slices per step. */
#define GRID_K_MAX 4096
/* K = GRID_K_FACTOR * v_ref * sqrt(N) / L: the measured optimum (see the top; the prefilter
 * makes a pair check several times cheaper than binning a particle). -DGRID_K_FACTOR=...
 * overrides it for tuning sweeps. */
#ifndef GRID_K_FACTOR
#define GRID_K_FACTOR 0.2
#endif
/* At most N / GRID_K_PER_N slices. */
#define GRID_K_PER_N 16
/* Widest radix digit: a 2^16-entry histogram. */
#define GRID_RADIX_MAX_BITS 16
/* Bins of the speed histogram that picks v_ref. */
#define GRID_SPEED_BINS 1024
/* v_ref leaves at most N / GRID_WIDE_SHARE particles faster than itself ("wide"). */
#define GRID_WIDE_SHARE 128
/* A grid counts as dense, and is counting-sorted, up to half this many cells per particle. */
#define GRID_DENSE_CELLS_PER_PARTICLE 8
#define GRID_DENSE_CELLS_MIN 4096
/* Bands of rows are used when slices are fewer than this many per thread. */
#define GRID_ITEMS_PER_THREAD 1
/* With more than one thread, up to this N a work item is one slice (the state fits in cache;
 * finest load balance); above, a thread takes a few long blocks of slices, which keeps memory
 * access sequential. One thread takes all the slices as one block: each slice's binning then
 * starts from the slice before's order, which on the report benchmark took 0.236 s against
 * 0.246 s for slices from the step's order (the order a second block would have to start from,
 * so with two threads single slices balance better). */
#define GRID_SMALL_N 32768
/* Flag bits of a binned box: reaches the next column, the next row; wider than 2 cells. */
#define GRID_EXT_X 1
#define GRID_EXT_Y 2
#define GRID_WIDE 4
#define GRID_EXT_BITS 2

/* The rounding delta must cover: the pair kernel's type, or double, whichever is coarser (the
 * slice times and the near test are double; the float binning has its own margin, below). */
#if defined(SIM_REAL_F32)
#define GRID_EPS ((double)FLT_EPSILON)
#else
#define GRID_EPS DBL_EPSILON
#endif

/* The float prefilter (see "The slice test" above): a run of entries is tested four at a time
 * in float, one 128-bit vector (Zen1's FP width), with the reach grown by
 * GRID_F32_MARGIN * FLT_EPSILON * B, where B bounds every float it reads (|coordinate| and
 * |displacement| <= B / 2): a generous multiple of the float rounding, which is about 12
 * FLT_EPSILON B on each end of the relative segment. Below GRID_F32_SPAN_MAX every square of a
 * coordinate is finite; a product that overflows (|p x w|^2 or r2 |w|^2 of a far pair) is
 * +inf, which only ever rejects a far pair or passes one. Above it, the scene gets one slice
 * and one cell, and zeros that pass (the double test decides). */
#define GRID_LANES 4
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
    int32_t *cx0, *cy0, *flag;   /* per input item: corner cell and flags */
    int32_t *scell;              /* dense grids: cell of each entry */
    uint8_t *sext;               /* reach bits of each entry */
    int32_t *pos;                /* dense grids: where each half-cell's entries begin */
    uint64_t pos_cap;            /* half-cells pos can hold */
    uint64_t *ent, *tmp, *skey;  /* sparse grids: radix words, radix buffer, cell of each entry */
    uint32_t *hist;              /* radix histogram */
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

/* ---- geometry: one function each, used for binning and for every later decision ---- */

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
    *flag = (b > a) * GRID_EXT_X + (d > c) * GRID_EXT_Y + ((b - a > 1) | (d - c > 1)) * GRID_WIDE;
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
static inline long near_pair(const grid_particle *restrict part, const double *restrict tk,
                             double reach2, int32_t i, int32_t j, int k)
{
    const grid_particle a = part[i], b = part[j];
    return near_in_slice(b.x - a.x, b.y - a.y, b.vx - a.vx, b.vy - a.vy, tk[k], tk[k + 1],
                         reach2);
}

/* The prefilter, four pairs at once: do the relative segments from p to p + w come within
 * sqrt(r2) of the origin? An end within reach, or the closest point inside the segment (moving
 * closer at p, away at p + w) with |p x w|^2 <= r2 |w|^2: no division, and the cross product
 * only loses to rounding what the margin covers (its error over |w| is about FLT_EPSILON |p|).
 * All lanes -1 or 0. */
static inline grid_vi near_f32(grid_vf px, grid_vf py, grid_vf wx, grid_vf wy, float r2)
{
    const grid_vf qx = px + wx, qy = py + wy, cr = px * wy - py * wx;
    const grid_vf ww = wx * wx + wy * wy, pw = px * wx + py * wy;
    /* q.w = p.w + |w|^2: off by a few FLT_EPSILON (|p| + |w|) |w|, which moves the split
     * between an end and the inside by a distance the margin covers. */
    return (px * px + py * py <= r2) | (qx * qx + qy * qy <= r2) |
           ((pw < 0) & (pw + ww > 0) & (cr * cr <= r2 * ww));
}

/* ---- the plan of a step ---- */

static int bits_for(uint64_t v) /* bits needed to hold values < v (v >= 1) */
{
    int b = 0;
    while (b < 64 && (v - 1) >> b)
        b++;
    return b;
}

static void plan_step(const sim_world *w, grid_scratch *s, grid_plan *g, int threads)
{
    const int32_t n = w->n;
    double minx = HUGE_VAL, maxx = -HUGE_VAL, miny = HUGE_VAL, maxy = -HUGE_VAL, vmax = 0;
    for (int32_t i = 0; i < n; i++) {
        const double x = (double)w->x[i], y = (double)w->y[i];
        const double vx = (double)w->vx[i], vy = (double)w->vy[i];
        s->part[i] = (grid_particle){x, y, vx, vy};
        minx = x < minx ? x : minx, maxx = x > maxx ? x : maxx;
        miny = y < miny ? y : miny, maxy = y > maxy ? y : maxy;
        const double ax = fabs(vx), ay = fabs(vy), a = ax > ay ? ax : ay;
        vmax = a > vmax ? a : vmax;
    }
    const double L = (double)w->L, r = (double)w->r;
    /* Padding: far above the rounding of the pair kernel and of the slice times. */
    const double delta = 4 * sqrt(GRID_EPS) * (L + 2 * vmax + 4 * r);
    /* The binning and the prefilter work in float, relative to the grid's corner. Every float
     * they compute (positions within [-vmax, span + vmax] of the corner, displacements, their
     * differences) is at most `bound` / 2 in magnitude: span <= extent + 2 vmax + 2 rpad, and
     * rpad's margin (below) is under 1e-5 bound. Each such float is within a few FLT_EPSILON
     * bound of its exact value, so a margin of GRID_F32_MARGIN FLT_EPSILON bound on the boxes
     * and on the prefilter's reach covers the rounding many times over: near in a slice (2r +
     * delta, in double) implies that the float boxes overlap and that the prefilter passes. */
    const double extent = maxx - minx > maxy - miny ? maxx - minx : maxy - miny;
    const double bound = 1.001 * (2 * (extent + 3 * vmax + 2 * delta) + 8 * r);
    const double margin = GRID_F32_MARGIN * (double)FLT_EPSILON * bound;
    /* Magnitudes floats cannot carry, or an overflowing padding: one slice and one cell, and
     * zeros that the prefilter passes; still exact (every pair is looked at). */
    g->f32_off = !(bound < GRID_F32_SPAN_MAX);
    const int sane = !g->f32_off;

    /* v_ref: the axis speed that at most N / GRID_WIDE_SHARE particles exceed, to a bin. */
    double vref = vmax;
    if (vmax > 0 && sane) {
        uint32_t count[GRID_SPEED_BINS] = {0};
        const double scale = (GRID_SPEED_BINS - 1) / vmax;
        for (int32_t i = 0; i < n; i++) {
            const double ax = fabs(s->part[i].vx), ay = fabs(s->part[i].vy);
            count[(int)((ax > ay ? ax : ay) * scale)]++;
        }
        const int32_t allow = n / GRID_WIDE_SHARE;
        int32_t above = 0;
        int b = GRID_SPEED_BINS - 1;
        while (b > 0 && above + (int32_t)count[b] <= allow)
            above += (int32_t)count[b--];
        vref = (b + 1) / scale;
        if (vref > vmax)
            vref = vmax;
    }

    /* Slices: K ~ v_ref sqrt(N) / L, at least 1, at most v_ref / 2r. */
    double kf = GRID_K_FACTOR * vref * sqrt((double)n) / L;
    const double kcap = vref / (2 * r);
    if (kf > kcap)
        kf = kcap;
    if (kf > GRID_K_MAX)
        kf = GRID_K_MAX;
    /* A slice costs about N binning steps; past N / GRID_K_PER_N slices (reached only when an
     * outlier drives v_ref far above the bulk) slicing costs more than testing all pairs. */
    if (kf > (double)n / GRID_K_PER_N)
        kf = (double)n / GRID_K_PER_N;
    g->K = sane && kf >= 1 ? (int)(kf + 0.5) : 1;
    /* Small N: one slice per work item, so a multiple of the thread count balances them (the
     * candidates found do not depend on K, only the work does). */
    if (threads > 1 && n <= GRID_SMALL_N && g->K >= threads && g->K % threads &&
        g->K + threads <= GRID_K_MAX)
        g->K += threads - g->K % threads;
    for (int k = 0; k <= g->K; k++)
        s->tk[k] = (double)k / g->K;

    g->reach2 = (2 * r + delta) * (2 * r + delta);
    /* Rounded up to float: (1 + 8 FLT_EPSILON) covers the conversion's half an ulp. */
    const double rpad = (r + delta + margin) * (1 + 8 * (double)FLT_EPSILON);
    const double freach = 2 * r + delta + margin;
    g->rpad = (float)rpad;
    g->freach2 = (float)(freach * freach * (1 + 8 * (double)FLT_EPSILON));

    /* Cell size: the box width of a particle at v_ref. Region: where such particles go. */
    double h = vref / g->K + 2 * rpad;
    g->x0 = minx - vref - rpad;
    g->y0 = miny - vref - rpad;
    const double spanx = (maxx + vref + rpad) - g->x0;
    const double spany = (maxy + vref + rpad) - g->y0;
    const double span = spanx > spany ? spanx : spany;
    /* Radix words are (cell, reach bits, index) in 64 bits, cell < (rows + 2) * (columns + 3);
     * and a float holds every cell number of an axis exactly. */
    g->pbits = bits_for((uint64_t)n);
    int axis_bits = (64 - g->pbits - GRID_EXT_BITS - 4) / 2;
    if (axis_bits > FLT_MANT_DIG)
        axis_bits = FLT_MANT_DIG;
    const double cells_max = (double)((int64_t)1 << axis_bits) - 4;
    if (!(span / h <= cells_max))
        h = span / cells_max;
    if (sane && h > 0) {
        g->inv_h = (float)(1 / h);
        g->gx = (int32_t)(spanx * g->inv_h) + 1;
        g->gy = (int32_t)(spany * g->inv_h) + 1;
        if (g->gx > cells_max)
            g->gx = (int32_t)cells_max;
        if (g->gy > cells_max)
            g->gy = (int32_t)cells_max;
    } else { /* one cell, every pair looked at; still exact */
        g->inv_h = 0;
        g->gx = g->gy = 1;
    }
    g->topx = (float)(g->gx - 1), g->topy = (float)(g->gy - 1);
    for (int32_t e = 0; e < n; e++)
        particle_f32(&s->part[s->ord[e]], g, &s->bx[e], &s->by[e], &s->ux[e], &s->uy[e]);

    /* Work items. */
    int bands = 1;
    if (threads > 1 && g->K < GRID_ITEMS_PER_THREAD * threads)
        bands = (GRID_ITEMS_PER_THREAD * threads + g->K - 1) / g->K;
    if (bands > g->gy)
        bands = g->gy;
    g->band_rows = (g->gy + bands - 1) / bands;
    g->bands = (g->gy + g->band_rows - 1) / g->band_rows;
    if (threads == 1)
        g->blocks = 1; /* every slice from the one before */
    else if (g->bands > 1 || n <= GRID_SMALL_N)
        g->blocks = g->K;
    else
        g->blocks = g->K < 2 * threads ? g->K : 2 * threads;
}

/* ---- one slice ---- */

/* Every item's corner cell and flags in slice k (as a float). One loop the compiler
 * vectorises. */
static void slice_cells(int32_t m, const float *restrict bx, const float *restrict by,
                        const float *restrict ux, const float *restrict uy, float k,
                        const grid_plan *g, int32_t *restrict cx0, int32_t *restrict cy0,
                        int32_t *restrict flag)
{
    for (int32_t p = 0; p < m; p++)
        box_cells(slice_start(bx[p], ux[p], k), slice_start(by[p], uy[p], k), ux[p], uy[p], g,
                  &cx0[p], &cy0[p], &flag[p]);
}

/* LSD radix sort of a[0, n) on bits [shift, shift + kb); returns the buffer holding the
 * result (a or tmp). Stable. */
static uint64_t *radix_sort(uint64_t *a, uint64_t *tmp, int32_t n, int shift, int kb,
                            uint32_t *hist)
{
    if (kb <= 0 || n < 2)
        return a;
    /* Digits of about log2(n) - 1 bits: the histogram stays smaller than the data. */
    int dmax = bits_for((uint64_t)n) - 1;
    dmax = dmax < 6 ? 6 : dmax > GRID_RADIX_MAX_BITS ? GRID_RADIX_MAX_BITS : dmax;
    const int passes = (kb + dmax - 1) / dmax, d = (kb + passes - 1) / passes;
    const uint64_t mask = ((uint64_t)1 << d) - 1;
    for (int pass = 0; pass < passes; pass++) {
        const int sh = shift + pass * d;
        memset(hist, 0, ((size_t)1 << d) * sizeof *hist);
        for (int32_t i = 0; i < n; i++)
            hist[(a[i] >> sh) & mask]++;
        if (hist[(a[0] >> sh) & mask] == (uint32_t)n)
            continue;
        uint32_t sum = 0;
        for (uint64_t b = 0; b <= mask; b++) {
            const uint32_t c = hist[b];
            hist[b] = sum;
            sum += c;
        }
        for (int32_t i = 0; i < n; i++)
            tmp[hist[(a[i] >> sh) & mask]++] = a[i];
        uint64_t *t = a;
        a = tmp;
        tmp = t;
    }
    return a;
}

static int32_t lower_bound(const uint64_t *key, int32_t n, uint64_t v)
{
    int32_t lo = 0, hi = n;
    while (lo < hi) {
        const int32_t mid = lo + (hi - lo) / 2;
        if (key[mid] < v)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo;
}

/* What a slice reads: items [0, m) from arrays (ids: id[e], or e itself when id is NULL), then
 * items [m, m + nwide) are the particles wide[] (read from the scratch's particle array). */
typedef struct grid_src {
    const float *bx, *by, *ux, *uy;
    const int32_t *id;
    int32_t m;
    const int32_t *wide;
    int32_t nwide;
} grid_src;

typedef struct grid_ctx {
    const sim_world *w;
    const grid_scratch *s;
    const grid_plan *g;
    int k;
    sim_cand_buf *buf;
    int32_t *ord_next; /* the step's last slice: where the new cell order goes */
} grid_ctx;

/* A pair near in slice cx->k (particles a, b): test it, and push it from its one slice. */
static void pair_found(const grid_ctx *cx, int32_t a, int32_t b)
{
    const int32_t i = a < b ? a : b, j = a < b ? b : a;
    const grid_particle *part = cx->s->part;
    const double *tk = cx->s->tk, reach2 = cx->g->reach2;
    const int k = cx->k, K = cx->g->K;
    /* The decision for this slice, in the (i, j) order every slice uses. */
    if (!near_pair(part, tk, reach2, i, j, k))
        return;
    sim_real t;
    if (!sim_pair_time(cx->w, i, j, &t))
        return;
    int kt = (int)((double)t * K);
    if (kt > K - 1)
        kt = K - 1;
    if (kt != k) {
        if (near_pair(part, tk, reach2, i, j, kt))
            return; /* slice kt pushes it */
        for (int e = 0; e < k; e++)
            if (near_pair(part, tk, reach2, i, j, e))
                return; /* an earlier slice pushes it */
    }
    sim_cand_push(cx->buf, t, i, j);
}

/* One particle looked at against runs of entries: its prefilter floats and its id. */
typedef struct grid_probe {
    float x, y, wx, wy;
    int32_t id;
} grid_probe;

/* The prefilter on the chunk of entries [b, b + GRID_LANES) of z against probe a. */
static inline grid_vi chunk_near(const grid_set *z, int32_t b, const grid_probe *a, float r2)
{
    grid_vf X, Y, WX, WY;
    memcpy(&X, z->px + b, sizeof X), memcpy(&Y, z->py + b, sizeof Y);
    memcpy(&WX, z->ux + b, sizeof WX), memcpy(&WY, z->uy + b, sizeof WY);
    return near_f32(X - a->x, Y - a->y, WX - a->wx, WY - a->wy, r2);
}

/* Where chunk c of two runs begins: the n1 chunks of the run at lo1, then those at lo2. */
static inline int32_t chunk_start(int32_t c, int32_t n1, int32_t lo1, int32_t lo2)
{
    return c < n1 ? lo1 + c * GRID_LANES : lo2 + (c - n1) * GRID_LANES;
}

/* The prefilter over two runs of entries of z, [lo1, hi1) and [lo2, hi2) (either may be
 * empty), against probe a: every pair it passes goes to pair_found, which decides. One loop
 * over the chunks of both (measured as fast as two loops; one place for the bookkeeping). Reads
 * up to GRID_LANES - 1 entries past a run's end. Returns the pairs looked at. */
static inline int32_t run_prefilter(const grid_ctx *cx, const grid_set *z, int32_t lo1,
                                    int32_t hi1, int32_t lo2, int32_t hi2, const grid_probe *a)
{
    const float r2 = cx->g->freach2;
    const int32_t len1 = hi1 > lo1 ? hi1 - lo1 : 0, len2 = hi2 > lo2 ? hi2 - lo2 : 0;
    const int32_t n1 = (len1 + GRID_LANES - 1) / GRID_LANES;
    const int32_t n = n1 + (len2 + GRID_LANES - 1) / GRID_LANES;
    grid_vi any = {0, 0, 0, 0};
    /* Lanes past a run's end are not masked here: they are entries of the slice or the zeroed
     * padding, and at worst make a run fire; the second pass masks them. */
    for (int32_t c = 0; c < n; c++)
        any |= chunk_near(z, chunk_start(c, n1, lo1, lo2), a, r2);
    if (any[0] | any[1] | any[2] | any[3])
        for (int32_t c = 0; c < n; c++) {
            const int32_t b = chunk_start(c, n1, lo1, lo2);
            const grid_vi lane = {0, 1, 2, 3};
            const grid_vi hit = chunk_near(z, b, a, r2) & (lane < (c < n1 ? hi1 : hi2) - b);
            for (int l = 0; l < GRID_LANES; l++)
                if (hit[l])
                    pair_found(cx, a->id, z->id[b + l]);
        }
    return len1 + len2;
}

/* Slice k, band `band`: bin the source into th->set[out] / th->wide[out] (returning their
 * sizes) and look at every pair of the band once. */
static void run_slice(const grid_ctx *cx, grid_thread *th, int band, const grid_src *src,
                      int out, int32_t *ne_out, int32_t *nw_out)
{
    const grid_scratch *s = cx->s;
    const grid_plan *g = cx->g;
    const double reach2 = g->reach2;
    const float kf = (float)cx->k;
    const int32_t row0 = band * g->band_rows;
    const int32_t row1 = row0 + g->band_rows < g->gy ? row0 + g->band_rows : g->gy;
    /* Entries of row row1 take part as upper neighbours of the band's last row. */
    const int32_t rowlast = row1 < g->gy ? row1 : row1 - 1;
    const uint64_t spanx = (uint64_t)g->gx + 3;
    const int pbits = g->pbits, kshift = pbits + GRID_EXT_BITS;
    const uint64_t pmask = ((uint64_t)1 << pbits) - 1;
    const grid_particle *restrict part = s->part;
    const int32_t m = src->m, items = src->m + src->nwide;
    grid_set *dst = &th->set[out];
    int32_t *wide = th->wide[out];
    uint64_t tests = 0;

    /* Corner cells and flags of every item: the arrays vectorised, the few wide ones apart. */
    slice_cells(m, src->bx, src->by, src->ux, src->uy, kf, g, th->cx0, th->cy0, th->flag);
    for (int32_t e = m; e < items; e++) {
        float bx, by, ux, uy;
        particle_f32(&part[src->wide[e - m]], g, &bx, &by, &ux, &uy);
        box_cells(slice_start(bx, ux, kf), slice_start(by, uy, kf), ux, uy, g, &th->cx0[e],
                  &th->cy0[e], &th->flag[e]);
    }
#define GRID_ID(E) ((E) < m ? (src->id ? src->id[E] : (E)) : src->wide[(E) - m])
#define GRID_PUT(D, E)                                                                        \
    do {                                                                                      \
        float bx_, by_, ux_, uy_;                                                             \
        if ((E) < m) {                                                                        \
            bx_ = src->bx[E], by_ = src->by[E], ux_ = src->ux[E], uy_ = src->uy[E];           \
            dst->id[D] = src->id ? src->id[E] : (E);                                          \
        } else {                                                                              \
            const int32_t p_ = src->wide[(E) - m];                                            \
            particle_f32(&part[p_], g, &bx_, &by_, &ux_, &uy_);                               \
            dst->id[D] = p_;                                                                  \
        }                                                                                     \
        dst->bx[D] = bx_, dst->by[D] = by_, dst->ux[D] = ux_, dst->uy[D] = uy_;               \
        dst->px[D] = slice_start(bx_, ux_, kf), dst->py[D] = slice_start(by_, uy_, kf);       \
    } while (0)

    /* The entries of this band's rows (and of the row above it) in cell order. Cells are
     * numbered row-major with stride spanx from (row0, column -1), so that every neighbour of
     * a base cell has a number. */
    int32_t ne = 0, nw = 0, below = 0;
    const uint64_t ncell = (uint64_t)(rowlast - row0 + 2) * spanx + 3;
    const int dense = 2 * ncell <= th->pos_cap;
    int32_t *restrict pos = th->pos;
    if (dense) {
        /* Dense: a counting sort on the half-cell h = 2c + (reaches the next column), so that in
         * every cell the entries reaching the next column come last. pos[h + 2] counts half-cell
         * h; after the prefix sum pos[h + 1] is where h begins; the scatter advances it to where
         * h ends, which leaves h's entries in [pos[h], pos[h + 1]) and cell c's in
         * [pos[2c], pos[2c + 2]). */
        memset(pos, 0, (size_t)(2 * ncell + 2) * sizeof *pos);
        for (int32_t e = 0; e < items; e++) {
            const int32_t f = th->flag[e], cy = th->cy0[e];
            if (f & GRID_WIDE)
                wide[nw++] = GRID_ID(e);
            else if (cy >= row0 && cy <= rowlast)
                pos[2 * ((uint64_t)(cy - row0) * spanx + (uint64_t)th->cx0[e] + 1) +
                    (uint64_t)(f & GRID_EXT_X) + 2]++;
            else
                below += cy < row0;
        }
        for (uint64_t c = 1; c < 2 * ncell + 2; c++)
            pos[c] += pos[c - 1];
        for (int32_t e = 0; e < items; e++) {
            const int32_t f = th->flag[e], cy = th->cy0[e];
            if (!(f & GRID_WIDE) && cy >= row0 && cy <= rowlast) {
                const int32_t c = (int32_t)((cy - row0) * (int64_t)spanx + th->cx0[e] + 1);
                const int32_t d = pos[2 * c + (f & GRID_EXT_X) + 1]++;
                GRID_PUT(d, e);
                th->scell[d] = c;
                th->sext[d] = (uint8_t)(f & (GRID_EXT_X | GRID_EXT_Y));
            }
        }
        ne = pos[2 * ncell];
    } else {
        for (int32_t e = 0; e < items; e++) {
            const int32_t f = th->flag[e], cy = th->cy0[e];
            if (f & GRID_WIDE) {
                wide[nw++] = GRID_ID(e);
            } else if (cy >= row0 && cy <= rowlast) {
                const uint64_t key = (uint64_t)(cy - row0) * spanx + (uint64_t)th->cx0[e] + 1;
                th->ent[ne++] = key << kshift | (uint64_t)f << pbits | (uint64_t)e;
            } else {
                below += cy < row0;
            }
        }
        const uint64_t *ent = radix_sort(th->ent, th->tmp, ne, kshift, bits_for(ncell), th->hist);
        for (int32_t d = 0; d < ne; d++) {
            const uint64_t v = ent[d];
            const int32_t e = (int32_t)(v & pmask);
            GRID_PUT(d, e);
            th->skey[d] = v >> kshift;
            th->sext[d] = (uint8_t)(v >> pbits & ((1u << GRID_EXT_BITS) - 1));
        }
    }
#undef GRID_PUT
#undef GRID_ID
    *ne_out = ne;
    *nw_out = nw;
    const uint64_t base_end = (uint64_t)(row1 - row0) * spanx;
    const int32_t nbase = dense ? pos[2 * base_end] : lower_bound(th->skey, ne, base_end);
    if (cx->ord_next) {
        /* The bands' base entries, in band order, then the wide particles: every particle
         * once, in this slice's cell order. */
        memcpy(cx->ord_next + below, dst->id, (size_t)nbase * sizeof(int32_t));
        if (band == 0)
            memcpy(cx->ord_next + (s->n - nw), wide, (size_t)nw * sizeof(int32_t));
    }

    const uint8_t *restrict sext = th->sext;

    /* Normal pairs, from the base cells of this band. Entry a of cell c = (cx, row) is looked
     * at against two runs of entries: the rest of its cell, and the next cell when it reaches
     * the next column; then, when it reaches the next row, the cells (cx-1 .. cx+1) of the row
     * above (cx+1 only when it reaches the next column). A pair of a run that cannot intersect
     * (a cx-1 box that does not reach column cx) is never near, and no pair is in a run of both
     * of its entries, so each is looked at once. A run goes through the float prefilter, then
     * pair_found decides where it fired. */
#define GRID_RUNS(A, LO1, HI1, LO2, HI2)                                                      \
    do {                                                                                      \
        const grid_probe p_ = {dst->px[A], dst->py[A], dst->ux[A], dst->uy[A], dst->id[A]};   \
        tests += (uint64_t)run_prefilter(cx, dst, (LO1), (HI1), (LO2), (HI2), &p_);           \
    } while (0)

    if (dense) {
        const int32_t w1 = (int32_t)spanx;
        const int32_t *restrict scell = th->scell;
        for (int32_t a = 0; a < nbase; a++) {
            const int32_t c = scell[a];
            const unsigned ex = sext[a], xr = ex & GRID_EXT_X;
            /* The rest of cell c (and cell c + 1); the up-left cell's entries that reach its
             * next column, the up cell (and the up-right one). */
            const int up = (ex & GRID_EXT_Y) != 0;
            GRID_RUNS(a, a + 1, pos[2 * (c + 1 + xr)], up ? pos[2 * (c + w1 - 1) + 1] : 0,
                      up ? pos[2 * (c + w1 + 1 + xr)] : 0);
        }
    } else {
        /* The same runs, found in the list of keys: the start of the cell's run (run_beg), the
         * end of its right neighbour, and a pointer into the row above that only moves on. */
        const uint64_t *restrict skey = th->skey;
        int32_t beg = 0, up = 0;
        while (beg < ne && skey[beg] < base_end) {
            const uint64_t key = skey[beg];
            int32_t end = beg;
            while (end < ne && skey[end] == key)
                end++;
            int32_t right_end = end;
            while (right_end < ne && skey[right_end] == key + 1)
                right_end++;
            while (up < ne && skey[up] < key + spanx - 1)
                up++;
            int32_t q = up;
            while (q < ne && skey[q] <= key + spanx)
                q++;
            const int32_t up_end = q;
            while (q < ne && skey[q] == key + spanx + 1)
                q++;
            const int32_t up_end_x = q;
            for (int32_t a = beg; a < end; a++) {
                const unsigned ex = sext[a];
                GRID_RUNS(a, a + 1, ex & GRID_EXT_X ? right_end : end, up,
                          ex & GRID_EXT_Y ? (ex & GRID_EXT_X ? up_end_x : up_end) : up);
            }
            beg = end;
        }
    }
#undef GRID_RUNS

    /* Wide boxes against the entries whose base cell is in this band: those with a corner cell
     * in the wide box's range or one column / row before it. */
    for (int32_t m2 = 0; m2 < nw; m2++) {
        const int32_t p = wide[m2];
        float bx, by;
        grid_probe pa = {.id = p};
        particle_f32(&part[p], g, &bx, &by, &pa.wx, &pa.wy);
        pa.x = slice_start(bx, pa.wx, kf), pa.y = slice_start(by, pa.wy, kf);
        int32_t cxa, cxb, cya, cyb;
        axis_cells(pa.x, pa.wx, g->rpad, g->inv_h, g->topx, &cxa, &cxb);
        axis_cells(pa.y, pa.wy, g->rpad, g->inv_h, g->topy, &cya, &cyb);
        const int32_t ra = cya - 1 > row0 ? cya - 1 : row0;
        const int32_t rb = cyb < row1 - 1 ? cyb : row1 - 1;
        for (int32_t row = ra; row <= rb; row++) {
            /* Cells (cxa - 1 .. cxb, row): numbers base + cxa .. base + cxb + 1. */
            const uint64_t base = (uint64_t)(row - row0) * spanx;
            int32_t lo, hi;
            if (dense) {
                lo = pos[2 * (base + (uint64_t)cxa)];
                hi = pos[2 * (base + (uint64_t)cxb + 2)];
            } else {
                lo = lower_bound(th->skey, ne, base + (uint64_t)cxa);
                hi = lower_bound(th->skey, ne, base + (uint64_t)cxb + 2);
            }
            tests += (uint64_t)run_prefilter(cx, dst, lo, hi, 0, 0, &pa);
        }
    }
    /* Wide boxes against each other, once per slice. */
    if (band == 0)
        for (int32_t m2 = 0; m2 < nw; m2++)
            for (int32_t q = m2 + 1; q < nw; q++) {
                tests++;
                if (near_pair(part, s->tk, reach2, wide[m2], wide[q], cx->k))
                    pair_found(cx, wide[m2], wide[q]);
            }
    cx->buf->pair_tests += tests;
}

/* Slices [k0, k1) of band `band`; each slice after the first reads the previous one's entries,
 * already in nearly the right order (only possible when the band is the whole grid). */
static void run_item(const sim_world *w, const grid_scratch *s, grid_thread *th,
                     const grid_plan *g, int k0, int k1, int band, sim_cand_buf *buf)
{
    grid_src src = {.bx = s->bx, .by = s->by, .ux = s->ux, .uy = s->uy, .id = s->ord, .m = s->n,
                    .wide = NULL, .nwide = 0};
    int out = 0;
    for (int k = k0; k < k1; k++) {
        const grid_ctx cx = {.w = w, .s = s, .g = g, .k = k, .buf = buf,
                             .ord_next = k == g->K - 1 ? s->ord_next : NULL};
        int32_t ne, nw;
        run_slice(&cx, th, band, &src, out, &ne, &nw);
        const grid_set *z = &th->set[out];
        src = (grid_src){.bx = z->bx, .by = z->by, .ux = z->ux, .uy = z->uy, .id = z->id, .m = ne,
                         .wide = th->wide[out], .nwide = nw};
        out ^= 1;
    }
}

static void find_pairs(const sim_world *w, sim_pair_sink *sink)
{
    grid_scratch *s = sink->scratch;
    if (w->n < 2)
        return;
    grid_plan g;
    plan_step(w, s, &g, sink->threads);
    const int threads = sink->threads;
    const int items = g.bands > 1 ? g.K * g.bands : g.blocks;
#pragma omp parallel num_threads(threads) if (threads > 1)
    {
        const int tid = omp_get_thread_num();
        sim_cand_buf *buf = sim_sink_buf(sink, tid);
        const double t0 = sim_busy_start();
#pragma omp for schedule(dynamic, 1) nowait
        for (int i = 0; i < items; i++) {
            buf->chunks++;
            if (g.bands > 1)
                run_item(w, s, &s->th[tid], &g, i / g.bands, i / g.bands + 1, i % g.bands, buf);
            else
                run_item(w, s, &s->th[tid], &g, (int)((int64_t)i * g.K / items),
                         (int)((int64_t)(i + 1) * g.K / items), 0, buf);
        }
        sim_busy_stop(buf, t0);
    }
    int32_t *t = s->ord;
    s->ord = s->ord_next;
    s->ord_next = t;
}

const sim_variant sim_variant_def = {
    .name = "grid",
    .exact = true,
    .parallel = true,
    .scratch_create = scratch_create,
    .scratch_destroy = scratch_destroy,
    .find_pairs = find_pairs,
};
