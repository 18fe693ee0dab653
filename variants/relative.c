/*
 * relative: the collision test of "Pool Hall Lessons" (van den Heuvel and Jackson, Gamasutra
 * 2002), which the seed report's Section 7.1 tried. The pair is reduced to one disc moving at
 * the relative velocity past a fixed one, and rejected as early as possible:
 *
 *   0. overlapping at step start (distance < 2r): they pass through (SPEC, not PHL);
 *   1. the movement over the step is shorter than the gap (distance - 2r);
 *   2. it points away (b >= 0);
 *   3. the closest approach exceeds 2r;
 * and only then is the contact time computed: the distance moved to the closest approach,
 * minus the half-chord sqrt((2r)^2 - closest^2), over the length of the movement; a contact
 * beyond the movement (after the step) is rejected.
 *
 * Where PHL loses digits: its closest approach is |C|^2 - (C.N)^2, which cancels when the discs
 * are far apart relative to r (the report's large-L failure). Here the squared closest distance
 * is cross^2 / a with cross = dx*Dy - dy*Dx, a = |D|^2, as SPEC's discriminant does. The boundary
 * cases decide as SPEC does: touching discs (distance == 2r) that approach collide at t = 0, a
 * tangent path (closest == 2r) is a contact, a contact at exactly t = 1 counts.
 *
 * The arithmetic differs from SPEC's (square roots of the distance and of the movement, a
 * division by the movement's length), so the contact times differ from seq's by rounding; the
 * core sorts and resolves the candidates exactly as for every variant. Not exact: how far it
 * strays from seq is measured (tests/c/grid_scenes.sh prints it for every scene).
 *
 * Speed: as in the shared kernel, a branch-free pass over a block of j (vectorised) first keeps
 * the blocks where some pair survives conservative forms of tests 0, 2 and 3 (no square root,
 * no division: never stricter than the scalar test); the PHL test above then runs, with its
 * early exits, on those blocks only. The outer loop is shared out with a dynamic schedule.
 */
#include <float.h>

#include "core/sim.h"

/* j-block of the filter pass (as in the shared kernel). */
#define REL_BLOCK 64

/* The filter's margin on test 3, a few units of the real type's rounding: the scalar test
 * compares cross^2 / a with (2r)^2, the filter cross^2 with (2r)^2 * a, which may round the
 * other way. */
#if defined(SIM_REAL_F32)
#define REL_EPS FLT_EPSILON
#else /* double, and __float128 (a wider margin than it needs; any wider one is still safe) */
#define REL_EPS DBL_EPSILON
#endif
#define REL_SLACK ((sim_real)1 + 16 * (sim_real)REL_EPS)

/* PHL for particles i < j: d = pj - pi, D = vj - vi (i moves by -D as seen from j). True and
 * *t set when the pair is a candidate (contact at t in [0, 1]). Comparisons are written so that
 * NaN (only from absurd magnitudes) rejects. */
static inline bool phl_time(sim_real dx, sim_real dy, sim_real ddx, sim_real ddy, sim_real diam,
                            sim_real diam2, sim_real *t)
{
    const sim_real dist2 = dx * dx + dy * dy;
    const sim_real c = dist2 - diam2;
    if (!(c >= 0))
        return false; /* 0. overlapping at step start: they pass through */
    const sim_real a = ddx * ddx + ddy * ddy;
    const sim_real move = SIM_SQRT(a);
    if (move < SIM_SQRT(dist2) - diam)
        return false; /* 1. the movement is shorter than the gap */
    const sim_real b = dx * ddx + dy * ddy;
    if (!(b < 0))
        return false; /* 2. not approaching */
    if (c == 0) {
        /* Touching and approaching: contact now. Decided before the closest approach, whose
         * cross^2 / a is 0/0 when |D|^2 underflows to 0 (SPEC: touching discs that approach
         * collide at t = 0, however slowly). */
        *t = 0;
        return true;
    }
    const sim_real cross = dx * ddy - dy * ddx;
    const sim_real closest2 = cross * cross / a;
    if (!(closest2 <= diam2))
        return false; /* 3. they miss */
    const sim_real along = -b / move;                         /* to the closest approach */
    const sim_real travel = along - SIM_SQRT(diam2 - closest2); /* to the first contact */
    if (!(travel <= move))
        return false; /* the contact comes after the step */
    *t = travel > 0 ? travel / move : 0;
    return true;
}

/* Conservative forms of tests 0, 2 and 3: true for every pair phl_time may accept. A long, so
 * that the vectorised loop keeps 64-bit lanes. */
static inline long phl_may_hit(sim_real dx, sim_real dy, sim_real ddx, sim_real ddy,
                               sim_real diam2)
{
    const sim_real c = (dx * dx + dy * dy) - diam2;
    const sim_real b = dx * ddx + dy * ddy;
    const sim_real cross = dx * ddy - dy * ddx;
    const sim_real a = ddx * ddx + ddy * ddy;
    return (c >= 0) & (b < 0) & (cross * cross <= diam2 * a * REL_SLACK);
}

static void scan_row(const sim_world *w, int32_t i, sim_cand_buf *buf)
{
    const sim_real *restrict x = w->x, *restrict y = w->y;
    const sim_real *restrict vx = w->vx, *restrict vy = w->vy;
    const sim_real xi = x[i], yi = y[i], vxi = vx[i], vyi = vy[i];
    const sim_real diam = 2 * w->r, diam2 = w->diam2;
    const int32_t n = w->n;
    for (int32_t j0 = i + 1; j0 < n; j0 += REL_BLOCK) {
        const int32_t j1 = n - j0 < REL_BLOCK ? n : j0 + REL_BLOCK;
        long any = 0;
        for (int32_t j = j0; j < j1; j++)
            any |= phl_may_hit(x[j] - xi, y[j] - yi, vx[j] - vxi, vy[j] - vyi, diam2);
        if (!any)
            continue;
        for (int32_t j = j0; j < j1; j++) {
            sim_real t;
            if (phl_time(x[j] - xi, y[j] - yi, vx[j] - vxi, vy[j] - vyi, diam, diam2, &t))
                sim_cand_push(buf, t, i, j);
        }
    }
    if (n > i + 1)
        buf->pair_tests += (uint64_t)(n - i - 1);
}

static void find_pairs(const sim_world *w, sim_pair_sink *sink)
{
    sim_rows_dynamic(w, sink, scan_row); /* omp for schedule(dynamic) */
}

/* one region per step, one grab per row (sim_rows_dynamic) */
static const sim_sync sync = {.regions = {.per_step = 1}, .grabs = {.per_row = 1}};

const sim_variant sim_variant_def = {
    .name = "relative",
    .summary =
        "\"Pool Hall Lessons\" relative-velocity test with early rejections, dynamic outer loop",
    .exact = false,
    .parallel = true,
    .all_pairs = false,
    .repairs = NULL,
    .sync = &sync,
    .find_pairs = find_pairs,
};
