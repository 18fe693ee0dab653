/*
 * grid_finder.c: the finder (grid_find_pairs): the plan of the step, then its slices' work
 * items shared out to the threads, alone, on a team that bins every particle in every band
 * (small scenes), or on a team that cuts every slice into bands. The pieces that do the work are
 * the other files of variants/grid/ (grid.h lists them).
 */
#include <stdbool.h>
#include <string.h>

#include <omp.h>

#include "grid.h"

/* Thread `me` of `team`'s part of the step's plan: its loops over particles shared out (each
 * thread merges every thread's extent and speed counts in the same order, so all make the same
 * plan); three barriers, the last after the binning's floats are written. */
static void plan_on_team(const sim_world *w, grid_scratch *s, int me, int team, grid_plan *g)
{
    const int32_t i0 = (int32_t)((int64_t)w->n * me / team);
    const int32_t i1 = (int32_t)((int64_t)w->n * (me + 1) / team);
    grid_extent_of(w, i0, i1, &s->team.extent[me]);
#pragma omp barrier
    grid_extent e = s->team.extent[0];
    for (int t = 1; t < team; t++)
        grid_extent_merge(&e, &s->team.extent[t]);
    const int speeds = grid_speeds_needed(w, &e);
    uint32_t *mine = s->team.speeds + (size_t)me * GRID_SPEED_BINS;
    memset(mine, 0, GRID_SPEED_BINS * sizeof *mine);
    if (speeds)
        grid_speed_count(w, i0, i1, e.vmax, mine);
#pragma omp barrier
    uint32_t count[GRID_SPEED_BINS] = {0};
    for (int t = 0; t < team && speeds; t++)
        for (int b = 0; b < GRID_SPEED_BINS; b++)
            count[b] += s->team.speeds[(size_t)t * GRID_SPEED_BINS + b];
    grid_plan_make(w, &e, count, s, g, team);
    grid_plan_floats(w, s, g, i0, i1);
    if (me == 0)
        grid_plan_times(s, g);
#pragma omp barrier
}

/* Thread `me` of `team` on a large scene: the plan, then the slices cut into bands. */
static void find_on_team(const sim_world *w, grid_scratch *s, int me, int team, sim_cand_buf *buf)
{
    grid_plan g;
    plan_on_team(w, s, me, team, &g);
    if (g.bands > 1) {
        grid_run_team(w, s, &g, me, team, buf);
    } else if (me == 0) {
        const double t0 = sim_busy_start();
        grid_run_alone(w, s, &g, buf);
        sim_busy_stop(buf, t0);
    }
}

void grid_find_pairs(const sim_world *w, sim_pair_sink *sink)
{
    grid_scratch *s = sink->scratch;
    if (w->n < 2)
        return;
    if (sink->threads > 1 && w->n <= s->direct_n) {
        /* A step of a millisecond, in one region: below GRID_PLAN_TEAM_MIN threads the plan on
         * one thread and no barrier in the slices; from it the plan and each slice's keys
         * shared out (grid_run_direct). */
        const bool team_plan = sink->threads >= GRID_PLAN_TEAM_MIN;
        grid_plan g = {0};
        if (!team_plan)
            grid_plan_step(w, s, &g, sink->threads);
#pragma omp parallel num_threads(sink->threads) firstprivate(g)
        {
            const int me = omp_get_thread_num();
            sim_cand_buf *buf = sim_sink_buf(sink, me);
            const int team = omp_get_num_threads();
            if (team_plan)
                plan_on_team(w, s, me, team, &g);
            if (g.bands > 1) {
                grid_run_direct(w, s, &g, me, team, buf);
            } else if (me == 0) {
                const double t0 = sim_busy_start();
                grid_run_alone(w, s, &g, buf);
                sim_busy_stop(buf, t0);
            }
        }
    } else if (sink->threads == 1) {
        grid_plan g;
        grid_plan_step(w, s, &g, 1);
        sim_cand_buf *buf = sim_sink_buf(sink, 0);
        const double t0 = sim_busy_start();
        grid_run_alone(w, s, &g, buf);
        sim_busy_stop(buf, t0);
    } else {
#pragma omp parallel num_threads(sink->threads)
        find_on_team(w, s, omp_get_thread_num(), omp_get_num_threads(),
                     sim_sink_buf(sink, omp_get_thread_num()));
    }
    int32_t *t = s->ord;
    s->ord = s->ord_next;
    s->ord_next = t;
}
