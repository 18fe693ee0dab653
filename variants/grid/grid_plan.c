/*
 * grid_plan.c: the plan of one step (grid_plan_step): the reference speed v_ref, the number of
 * time slices K, the cell size and the grid's extent, the padding that makes the float binning
 * safe (delta, margin), and how the work is cut into items for the threads.
 */
#include <math.h>

#include "grid.h"

/* The parameters below were chosen by interleaved measurements on the report benchmark
 * (N = 10^4), on N = 4 10^4 to 10^6, and on the dense slow scene; docs/grid_bound.md ("The
 * plan's parameters") has the measurements. -D overrides the K factors, for tuning sweeps.
 *
 * With cells a box wide (sub 1), K = GRID_K_FACTOR * v_ref * sqrt(N) / L. The cell size is then
 * L / (factor sqrt(N)) whatever the speeds, about 1 / factor^2 discs a cell, and the best
 * factor is about sqrt(pair-check cost / binning cost): one factor fits every N
 * (docs/grid_design.md). */
#ifndef GRID_K_FACTOR
#define GRID_K_FACTOR 0.15
#endif
/* With cells a third of a box wide (sub = GRID_SUB_MAX) a pair check costs less against the
 * binning (fewer of the pairs in a neighbourhood are far apart), so slices are longer: K =
 * GRID_K_FACTOR_SUB * v_ref * sqrt(N) / L. At fixed density K is about factor sqrt(N) / 4
 * (v_ref near L / 4): on the report benchmark this factor gives one slice a step. */
#ifndef GRID_K_FACTOR_SUB
#define GRID_K_FACTOR_SUB 0.06
#endif
/* Subdivide a box's cell in sub x sub where a cell a box wide would hold at least
 * GRID_SUB_OCCUPANCY sub^2 discs: the report benchmark's hold about 150 (sub 3); on the dense
 * slow scene (bench.py dense: speeds of a radius a step, K = 1) a cell holds about 0.4, and
 * smaller cells there only add runs. Crowded cells are subdivided at every N: where the
 * slices' entries leave the cache (N = 4 10^5 and 10^6) the pairs saved still pay for the
 * extra runs. */
#define GRID_SUB_OCCUPANCY 6.0
/* At most N / GRID_K_PER_N slices. */
#define GRID_K_PER_N 16
/* v_ref leaves at most N / GRID_WIDE_SHARE particles faster than itself ("wide"). */
#define GRID_WIDE_SHARE 128

int grid_bits_for(uint64_t v)
{
    int b = 0;
    while (b < 64 && (v - 1) >> b)
        b++;
    return b;
}

/* K = factor * v_ref * sqrt(N) / L rounded, at least 1, at most v_ref / 2r, GRID_K_MAX and
 * N / GRID_K_PER_N; 1 where floats cannot carry the scene (sane == 0). */
static int slice_count(double factor, double vref, int32_t n, double L, double r, int sane)
{
    double kf = factor * vref * sqrt((double)n) / L;
    const double kcap = vref / (2 * r);
    if (kf > kcap)
        kf = kcap;
    if (kf > GRID_K_MAX)
        kf = GRID_K_MAX;
    /* A slice costs about N binning steps; past N / GRID_K_PER_N slices (reached only when an
     * outlier drives v_ref far above the bulk) slicing costs more than testing all pairs. */
    if (kf > (double)n / GRID_K_PER_N)
        kf = (double)n / GRID_K_PER_N;
    return sane && kf >= 1 ? (int)(kf + 0.5) : 1;
}

/* K shared out to `parts` finders (grid_scratch's slice_parts) in equal shares: the multiple of
 * parts nearest to K (the larger one on a tie) that slice_count's bounds allow (at most
 * v_ref / 2r, GRID_K_MAX and N / GRID_K_PER_N), else K itself (fewer slices than parts: some
 * parts have none). Every K finds the same candidates; a multiple evens the parts' work out. */
static int share_slices(int K, int parts, double vref, int32_t n, double r, int sane)
{
    if (parts <= 1 || !sane || K % parts == 0)
        return K;
    double cap = vref / (2 * r);
    if (cap > GRID_K_MAX)
        cap = GRID_K_MAX;
    if (cap > (double)n / GRID_K_PER_N)
        cap = (double)n / GRID_K_PER_N;
    const int down = K / parts * parts, up = down + parts;
    if (up <= cap && (down == 0 || up - K <= K - down))
        return up;
    return down > 0 ? down : K;
}

void grid_extent_of(const sim_world *w, int32_t i0, int32_t i1, grid_extent *e)
{
    double minx = HUGE_VAL, maxx = -HUGE_VAL, miny = HUGE_VAL, maxy = -HUGE_VAL, vmax = 0;
    for (int32_t i = i0; i < i1; i++) {
        const double x = (double)w->x[i], y = (double)w->y[i];
        const double vx = (double)w->vx[i], vy = (double)w->vy[i];
        minx = x < minx ? x : minx, maxx = x > maxx ? x : maxx;
        miny = y < miny ? y : miny, maxy = y > maxy ? y : maxy;
        const double ax = fabs(vx), ay = fabs(vy), a = ax > ay ? ax : ay;
        vmax = a > vmax ? a : vmax;
    }
    *e = (grid_extent){minx, maxx, miny, maxy, vmax};
}

void grid_extent_merge(grid_extent *a, const grid_extent *b)
{
    a->minx = b->minx < a->minx ? b->minx : a->minx, a->maxx = b->maxx > a->maxx ? b->maxx : a->maxx;
    a->miny = b->miny < a->miny ? b->miny : a->miny, a->maxy = b->maxy > a->maxy ? b->maxy : a->maxy;
    a->vmax = b->vmax > a->vmax ? b->vmax : a->vmax;
}

/* Padding: far above the rounding of the pair kernel and of the slice times. */
static double plan_delta(const sim_world *w, const grid_extent *e)
{
    return 4 * sqrt(GRID_EPS) * ((double)w->L + 2 * e->vmax + 4 * (double)w->r);
}

/* The binning and the prefilter work in float, relative to the grid's corner. Every float they
 * compute (positions within [-vmax, span + vmax] of the corner, displacements, their
 * differences) is at most the bound / 2 in magnitude: span <= extent + 2 vmax + 2 rpad, and
 * rpad's margin (grid_plan_make) is under 1e-5 bound. Each such float is within a few
 * FLT_EPSILON bound of its exact value, so a margin of GRID_F32_MARGIN FLT_EPSILON bound on the
 * boxes and on the prefilter's reach covers the rounding many times over: near in a slice
 * (2r + delta, in double) implies that the float boxes overlap and that the prefilter passes. */
static double plan_bound(const sim_world *w, const grid_extent *e)
{
    const double extent =
        e->maxx - e->minx > e->maxy - e->miny ? e->maxx - e->minx : e->maxy - e->miny;
    return 1.001 * (2 * (extent + 3 * e->vmax + 2 * plan_delta(w, e)) + 8 * (double)w->r);
}

int grid_speeds_needed(const sim_world *w, const grid_extent *e)
{
    return e->vmax > 0 && plan_bound(w, e) < GRID_F32_SPAN_MAX;
}

void grid_speed_count(const sim_world *w, int32_t i0, int32_t i1, double vmax, uint32_t *count)
{
    const double scale = (GRID_SPEED_BINS - 1) / vmax;
    for (int32_t i = i0; i < i1; i++) {
        const double ax = fabs((double)w->vx[i]), ay = fabs((double)w->vy[i]);
        count[(int)((ax > ay ? ax : ay) * scale)]++;
    }
}

void grid_plan_floats(const sim_world *w, grid_scratch *s, const grid_plan *g, int32_t e0,
                      int32_t e1)
{
    for (int32_t e = e0; e < e1; e++) {
        const grid_particle q = grid_part(w, s->ord[e]);
        particle_f32(&q, g, &s->bx[e], &s->by[e], &s->ux[e], &s->uy[e]);
    }
}

void grid_plan_step(const sim_world *w, grid_scratch *s, grid_plan *g, int threads)
{
    grid_extent e;
    grid_extent_of(w, 0, w->n, &e);
    uint32_t count[GRID_SPEED_BINS] = {0};
    if (grid_speeds_needed(w, &e))
        grid_speed_count(w, 0, w->n, e.vmax, count);
    grid_plan_make(w, &e, count, s, g, threads);
    grid_plan_floats(w, s, g, 0, w->n);
    grid_plan_times(s, g);
}

void grid_plan_times(grid_scratch *s, const grid_plan *g)
{
    for (int k = 0; k <= g->K; k++)
        s->tk[k] = (double)k / g->K;
}

void grid_plan_make(const sim_world *w, const grid_extent *e, const uint32_t *count,
                    const grid_scratch *s, grid_plan *g, int threads)
{
    const int32_t n = w->n;
    const double minx = e->minx, maxx = e->maxx, miny = e->miny, maxy = e->maxy;
    const double vmax = e->vmax;
    const double L = (double)w->L, r = (double)w->r;
    const double delta = plan_delta(w, e);
    const double bound = plan_bound(w, e);
    const double margin = GRID_F32_MARGIN * (double)FLT_EPSILON * bound;
    /* Magnitudes floats cannot carry, or an overflowing padding: one slice and one cell, and
     * zeros that the prefilter passes; still exact (every pair is looked at). */
    g->f32_off = !(bound < GRID_F32_SPAN_MAX);
    const int sane = !g->f32_off;

    /* v_ref: the axis speed that at most N / GRID_WIDE_SHARE particles exceed, to a bin. */
    double vref = vmax;
    if (grid_speeds_needed(w, e)) {
        const double scale = (GRID_SPEED_BINS - 1) / vmax;
        const int32_t allow = n / GRID_WIDE_SHARE;
        int32_t above = 0;
        int b = GRID_SPEED_BINS - 1;
        while (b > 0 && above + (int32_t)count[b] <= allow)
            above += (int32_t)count[b--];
        vref = (b + 1) / scale;
        if (vref > vmax)
            vref = vmax;
    }

    const double rpad = (r + delta + margin) * (1 + 8 * (double)FLT_EPSILON);
    /* Cells per box width and slices (docs/grid_design.md, "Subdivided cells"): cells of 1 /
     * sub of a box, sub up to GRID_SUB_MAX, with GRID_K_FACTOR_SUB where a cell of a whole box
     * would hold at least GRID_SUB_OCCUPANCY sub^2 discs; else whole boxes and
     * GRID_K_FACTOR. */
    g->K = slice_count(GRID_K_FACTOR_SUB, vref, n, L, r, sane);
    const double h_sub = vref / g->K + 2 * rpad; /* the box width at v_ref */
    const double area = (maxx - minx + h_sub) * (maxy - miny + h_sub);
    const double per_cell = (double)n * h_sub * h_sub / area; /* discs a cell of h_sub */
    /* The largest sub with per_cell >= GRID_SUB_OCCUPANCY sub^2, by comparisons: where floats
     * cannot carry the scene, per_cell can be inf / inf, and a NaN converted to int is
     * undefined behaviour (seen with speeds of 1e200 under -fsanitize=float-cast-overflow). */
    int sub = 1;
    while (sane && sub < GRID_SUB_MAX && per_cell >= GRID_SUB_OCCUPANCY * (sub + 1) * (sub + 1))
        sub++;
    if (s->sub_force)
        sub = s->sub_force;
    g->sub = sub;
    if (sub == 1)
        g->K = slice_count(GRID_K_FACTOR, vref, n, L, r, sane);
    const int parts = s->slice_parts > 1 ? s->slice_parts : 1, part = parts > 1 ? s->slice_part : 0;
    g->K = share_slices(g->K, parts, vref, n, r, sane);
    g->k0 = part;
    g->kstep = parts;

    g->reach2 = (2 * r + delta) * (2 * r + delta);
    /* rpad, above, is rounded up to float: (1 + 8 FLT_EPSILON) covers the conversion's half an
     * ulp. */
    const double freach = 2 * r + delta + margin;
    g->rpad = (float)rpad;
    g->freach2 = (float)(freach * freach * (1 + 8 * (double)FLT_EPSILON));
    /* Every float displacement over a slice is at most vmax / K per axis (up to an ulp), so a
     * relative one at most 2 sqrt(2) vmax / K long. */
    const double sqrt2 = 1.4142135623730951;
    g->fend = (float)(freach * 2 * sqrt2 * vmax / g->K * (1 + 64 * (double)FLT_EPSILON));
    /* Where floats cannot carry the scene every prefilter float is 0, and each of its tests
     * must hold: the reach and end slack can be inf there, and the line test's r2 |w|^2 would
     * be inf * 0 = NaN (the absurd_speeds scene, speeds of 1e300). */
    if (g->f32_off)
        g->freach2 = g->fend = FLT_MAX;

    /* Cell size: 1 / sub of the box width of a particle at v_ref. Region: where such
     * particles go. */
    double h = (vref / g->K + 2 * rpad) / sub;
    g->x0 = minx - vref - rpad;
    g->y0 = miny - vref - rpad;
    const double spanx = (maxx + vref + rpad) - g->x0;
    const double spany = (maxy + vref + rpad) - g->y0;
    const double span = spanx > spany ? spanx : spany;
    /* Radix words are (cell, reach bits, index) in 64 bits, cell < (rows + sub + 1) *
     * (columns + 2 sub + 1) (grid_bins); and a float holds every cell number of an axis
     * exactly. */
    g->pbits = grid_bits_for((uint64_t)n);
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

    /* A team cuts every slice into a band of rows a thread (grid_scan.c). */
    g->bands = threads > 1 && g->gy > 1 ? threads : 1;
}
