/*
 * sim_walls.c: SPEC §2's wall candidates: every particle's wall time, in a vectorised pass over
 * blocks of particles, and the particles whose time is at most 1 appended in particle order.
 * The scalar form (sim_wall_time) is the reference the tests hold the pass to.
 */
#include <stdint.h>

#include <omp.h>

#include "sim_stepper.h"

/* Time for a centre at q moving at w to reach the wall ahead (SPEC §2); infinite when w == 0. */
static inline sim_real axis_time(sim_real q, sim_real w, sim_real lo, sim_real hi)
{
    if (w > 0)
        return (hi - q) / w;
    if (w < 0)
        return (lo - q) / w;
    return SIM_REAL_INF;
}

/* SPEC §2 wall time of a centre at (x, y) moving at (vx, vy). */
static inline sim_real wall_time(sim_real x, sim_real y, sim_real vx, sim_real vy, sim_real lo,
                                 sim_real hi)
{
    const sim_real tx = axis_time(x, vx, lo, hi), ty = axis_time(y, vy, lo, hi);
    return tx < ty ? tx : ty;
}

sim_real sim_wall_time(const sim_world *w, int32_t i)
{
    return wall_time(w->x[i], w->y[i], w->vx[i], w->vy[i], w->lo, w->hi);
}

sim_real sim_stepper_wall_time(const sim_stepper *s, int32_t i)
{
    return s->wall_t[i];
}

void sim_clear_walls(sim_stepper *s)
{
    for (int k = 0; k < s->threads; k++)
        s->walls[k].len = 0;
}

/* Append the wall candidates of particles [i0, i1) of the state (x, y, vx, vy) to buf, in
 * increasing i, and write every particle's wall time to wall_t. Blocks of SIM_WALL_BLOCK, in
 * three passes that each vectorise or need no branch (a fifth of the particles on the report
 * benchmark are candidates, at random: a branch on it mispredicts):
 *  1. the distance to the wall ahead on each axis (the wall is hi when w > 0, else lo);
 *  2. the axis times, the same IEEE operations as axis_time where w != 0, infinity where
 *     w == 0 (the division by 0 is computed and discarded), and their minimum, into wall_t.
 *     Passes 1 and 2 as one loop GCC 12 does not vectorise: jump threading turns the two
 *     selects on w into branches;
 *  3. an append that writes every particle and advances only past candidates. */
void sim_find_walls_range(sim_cand_buf *buf, sim_real *restrict wall_t,
                          const sim_real *restrict x, const sim_real *restrict y,
                          const sim_real *restrict vx, const sim_real *restrict vy, sim_real lo,
                          sim_real hi, int32_t i0, int32_t i1)
{
    sim_real ax[SIM_WALL_BLOCK], ay[SIM_WALL_BLOCK];
    for (int32_t b = i0; b < i1; b += SIM_WALL_BLOCK) {
        const int32_t len = i1 - b < SIM_WALL_BLOCK ? i1 - b : SIM_WALL_BLOCK;
        const sim_real *restrict xb = x + b, *restrict yb = y + b;
        const sim_real *restrict vxb = vx + b, *restrict vyb = vy + b;
        sim_real *restrict tw = wall_t + b;
        for (int32_t k = 0; k < len; k++) {
            ax[k] = (vxb[k] > 0 ? hi : lo) - xb[k];
            ay[k] = (vyb[k] > 0 ? hi : lo) - yb[k];
        }
        for (int32_t k = 0; k < len; k++) {
            const sim_real tx = ax[k] / vxb[k], ty = ay[k] / vyb[k];
            const sim_real txw = vxb[k] != 0 ? tx : SIM_REAL_INF;
            const sim_real tyw = vyb[k] != 0 ? ty : SIM_REAL_INF;
            tw[k] = txw < tyw ? txw : tyw;
        }
        if (!sim_cand_reserve(&buf->items, &buf->cap, buf->len + (size_t)len)) {
            buf->failed = true;
            return;
        }
        sim_cand *items = buf->items;
        size_t at = buf->len;
        for (int32_t k = 0; k < len; k++) {
            items[at] = (sim_cand){.t = tw[k], .i = b + k, .j = SIM_WALL};
            at += tw[k] <= 1;
        }
        buf->len = at;
    }
}

void sim_find_walls(sim_stepper *s, const sim_world *w)
{
    sim_clear_walls(s);
    const int32_t blocks = (w->n + SIM_WALL_BLOCK - 1) / SIM_WALL_BLOCK;
#pragma omp parallel num_threads(s->threads) if (sim_team_pays(s, w->n))
    {
        const int me = omp_get_thread_num();
        int32_t b0, b1, i0, i1;
        sim_share(blocks, me, omp_get_num_threads(), &b0, &b1);
        sim_block_span(w->n, b0, b1, &i0, &i1);
        sim_find_walls_range(&s->walls[me], s->wall_t, w->x, w->y, w->vx, w->vy, w->lo, w->hi, i0,
                             i1);
    }
}
