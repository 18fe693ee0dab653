/*
 * grid_geometry.h: the few functions every decision of the grid is made with, one each: a
 * particle in the binning's float terms, its cells in a slice, "near in slice k" in double
 * (near_pair), and the float prefilter's test of a vector of pairs (near_f32). Binning, the
 * prefilter and pair_found all call these, so they agree by construction.
 */
#ifndef GRID_GEOMETRY_H
#define GRID_GEOMETRY_H

#include "grid_state.h"

#if defined(__FMA__) || defined(__AVX__) || defined(__AVX512F__)
#include <immintrin.h>
#endif

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
static inline long near_pair(const grid_particle *restrict part, const double *restrict tk,
                             double reach2, int32_t i, int32_t j, int k)
{
    const grid_particle a = part[i], b = part[j];
    return near_in_slice(b.x - a.x, b.y - a.y, b.vx - a.vx, b.vy - a.vy, tk[k], tk[k + 1],
                         reach2);
}

/* a * b + c, rounded once where the machine has FMA. Only the float prefilter uses it: its
 * error bound (below) holds for a rounding of a * b and of the sum as well as for one rounding,
 * and it decides no output (the exact builds' rule, -ffp-contract=off, is for the double
 * arithmetic that does). 2-3% of the finder on the report benchmark (znver4, 9 interleaved
 * runs). */
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
 * within R = sqrt(r2) of the origin? It passes every pair that does (and some that do not;
 * the double test decides): p itself within reach, or the line within reach (|p x w|^2 <= r2
 * |w|^2, no division) with the closest point no further than R beyond either end along w
 * (p.w <= R |w| and (p + w).w >= -R |w|). The two ends are tested against R |w| bounded over
 * the slice, `tend` = R * (the longest |w|), instead of |w| itself: a pair whose closest point
 * is the far end q = p + w has q.w >= -|q| |w| >= -R |w| >= -tend, so it passes without q's
 * own distance being computed (2 multiplications and 3 additions fewer a vector: 4% of the
 * finder on the report benchmark, znver4, 9 interleaved runs). Rounding: the cross product
 * loses about FLT_EPSILON |p| |w| to it, and q.w = p.w + |w|^2 a few FLT_EPSILON (|p| + |w|)
 * |w|; the margin in R and in tend covers both. Lane l of the result is bit l.
 *
 * near_f32_line is the line test alone. A pair whose closest point is its start p, |p| <= R,
 * passes it too (|p x w| <= |p| |w| <= R |w|, and -R |w| <= p.w <= R |w| <= tend), and so does
 * every pair with w == 0 (all three sides are 0 then). near_f32 adds p's own distance and
 * leaves pairs with w == 0 to it (`ww > 0`): equal displacements would otherwise pass
 * whatever their distance. The runs test near_f32_line, which has 2 multiplications and a
 * comparison fewer, and near_f32 only on a chunk where a lane passed it (at most 1.7% of the
 * chunks on the report benchmark): the finder took 0.91x the time of near_f32 on every chunk
 * (report benchmark, one thread, medians of 9 interleaved runs), and a scene whose
 * displacements are all equal, where every lane passes the line test, pays near_f32 on its
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

#endif /* GRID_GEOMETRY_H */
