/*
 * sim_motion.c: the moves of the particles that had an accepted collision (SPEC §2 Motion),
 * a block of events at a time, in vector lanes.
 *
 * Why lanes: on the report benchmark 45% of the particles have an event every step (2,100 walls
 * and 1,200 pairs of 10,000), and scalar code, one event at a time, branches on the sign of
 * every velocity, on which axis is hit and on whether finish meets a wall: random outcomes, so
 * about one mispredicted branch per division, each emptying the pipeline that would otherwise
 * overlap the next event's divisions. Here every event runs the same straight-line code: each
 * alternative is computed and the SPEC's one selected, lane by lane (sim_sel), so a division
 * that SPEC skips is done and discarded (its result is never selected; a division by 0 is
 * harmless without traps).
 *
 * Exactness: every selected value comes from the same IEEE operations, in the same order, as
 * the scalar code (tests/c/test_core.c compares the two on random events, and run_scenes.sh
 * every variant with seq). GCC's vector extensions, not the auto-vectoriser: GCC 12 turns
 * these selects back into branches (jump threading, and sinking of the divisions under
 * -ftrapping-math) and then gives up vectorising. __float128 has no vector type: its build
 * runs the same code one lane wide.
 */
#include <stdint.h>

#include "sim_core.h"

/* Events per block: the lanes of a block live in stack arrays (L1) between the gather, the
 * arithmetic and the scatter. */
#define SIM_EVENT_BLOCK 64

#if defined(SIM_REAL_F128)
#define SIM_LANES 1
typedef sim_real sim_vreal;
typedef int sim_vmask;
#define SIM_LANE(v, l) (v)
static inline sim_vreal sim_sel(sim_vmask m, sim_vreal a, sim_vreal b)
{
    return m ? a : b;
}
#else
/* 32 bytes, AVX2's width, where AVX is enabled; else 16 (SSE2's): a 32-byte vector passed or
 * returned by value without AVX changes the ABI, which GCC warns of (-Wpsabi, an error under
 * -Werror), and a build with -march=x86-64 failed here. */
#if defined(__AVX__) || !(defined(__x86_64__) || defined(__i386__))
#define SIM_VECTOR_BYTES 32
#else
#define SIM_VECTOR_BYTES 16
#endif
#if defined(SIM_REAL_F32)
typedef int32_t sim_lane_int;
#else
typedef int64_t sim_lane_int;
#endif
#define SIM_LANES ((int)(SIM_VECTOR_BYTES / sizeof(sim_real)))
typedef sim_real sim_vreal __attribute__((vector_size(SIM_VECTOR_BYTES)));
/* What a comparison of two sim_vreal gives: all ones (true) or zero per lane. */
typedef sim_lane_int sim_vmask __attribute__((vector_size(SIM_VECTOR_BYTES)));
#define SIM_LANE(v, l) ((v)[l])
/* Per lane, a where m is true, else b: the bits, so the value is a or b exactly. */
static inline sim_vreal sim_sel(sim_vmask m, sim_vreal a, sim_vreal b)
{
    return (sim_vreal)((m & (sim_vmask)a) | (~m & (sim_vmask)b));
}
#endif

#define SIM_EVENT_VECTORS (SIM_EVENT_BLOCK / SIM_LANES)

static inline sim_vreal splat(sim_real v)
{
    sim_vreal r;
    for (int l = 0; l < SIM_LANES; l++)
        SIM_LANE(r, l) = v;
    return r;
}

/* The constants of a world, in lanes. */
typedef struct lanes_const {
    sim_vreal lo, hi, zero, one;
} lanes_const;

static lanes_const lanes_of(const sim_world *w)
{
    return (lanes_const){splat(w->lo), splat(w->hi), splat(0), splat(1)};
}

/* axis_time (sim_walls.c) in lanes: (wall ahead - q) / w, and +infinity where w == 0 (as
 * 1 / +0: w + 0 is w except that it turns -0 into +0). */
static inline sim_vreal axis_time_v(sim_vreal q, sim_vreal w, const lanes_const *c)
{
    const sim_vreal wall = sim_sel(w > c->zero, c->hi, c->lo);
    return sim_sel(w != c->zero, wall - q, c->one) / (w + c->zero);
}

static inline sim_vreal clamp_v(sim_vreal q, const lanes_const *c)
{
    return sim_sel(q < c->lo, c->lo, sim_sel(q > c->hi, c->hi, q));
}

/* SPEC §2's finish(rest) in lanes, then the clamp into the box. */
static inline void finish_v(sim_vreal *x, sim_vreal *y, sim_vreal vx, sim_vreal vy,
                            sim_vreal rest, const lanes_const *c)
{
    sim_vreal tx = axis_time_v(*x, vx, c), ty = axis_time_v(*y, vy, c);
    tx = sim_sel(tx < c->zero, c->zero, tx);
    ty = sim_sel(ty < c->zero, c->zero, ty);
    const sim_vreal tw = sim_sel(tx < ty, tx, ty);
    const sim_vmask stop = tw < rest;
    const sim_vreal xw = sim_sel(tx == tw, sim_sel(vx > c->zero, c->hi, c->lo), *x + tw * vx);
    const sim_vreal yw = sim_sel(ty == tw, sim_sel(vy > c->zero, c->hi, c->lo), *y + tw * vy);
    *x = clamp_v(sim_sel(stop, xw, *x + rest * vx), c);
    *y = clamp_v(sim_sel(stop, yw, *y + rest * vy), c);
}

/* One particle's state in lanes, SIM_EVENT_BLOCK of them. */
typedef struct lanes_state {
    sim_vreal x[SIM_EVENT_VECTORS], y[SIM_EVENT_VECTORS];
    sim_vreal vx[SIM_EVENT_VECTORS], vy[SIM_EVENT_VECTORS];
} lanes_state;

static void put_lane(lanes_state *st, int k, sim_real x, sim_real y, sim_real vx, sim_real vy)
{
    SIM_LANE(st->x[k / SIM_LANES], k % SIM_LANES) = x;
    SIM_LANE(st->y[k / SIM_LANES], k % SIM_LANES) = y;
    SIM_LANE(st->vx[k / SIM_LANES], k % SIM_LANES) = vx;
    SIM_LANE(st->vy[k / SIM_LANES], k % SIM_LANES) = vy;
}

static void take_lane(const lanes_state *st, int k, const sim_world *w, sim_real *nx,
                      sim_real *ny, int32_t i)
{
    nx[i] = SIM_LANE(st->x[k / SIM_LANES], k % SIM_LANES);
    ny[i] = SIM_LANE(st->y[k / SIM_LANES], k % SIM_LANES);
    w->vx[i] = SIM_LANE(st->vx[k / SIM_LANES], k % SIM_LANES);
    w->vy[i] = SIM_LANE(st->vy[k / SIM_LANES], k % SIM_LANES);
}

/* The lanes past the last event of a block get a copy of it: their results are dropped. A
 * block reads all its particles' state before it writes any, and blocks share no particle, so
 * the new velocities can go straight into the world's arrays. */
static int block_len(size_t count, size_t k0)
{
    return count - k0 < SIM_EVENT_BLOCK ? (int)(count - k0) : SIM_EVENT_BLOCK;
}

void sim_move_walls(const sim_world *w, const sim_cand *events, size_t count, size_t k0,
                    sim_real *nx, sim_real *ny)
{
    const lanes_const c = lanes_of(w);
    const int len = block_len(count, k0);
    lanes_state st;
    sim_vreal t[SIM_EVENT_VECTORS];
    const int vectors = (len + SIM_LANES - 1) / SIM_LANES;
    for (int k = 0; k < vectors * SIM_LANES; k++) {
        const sim_cand e = events[k0 + (size_t)(k < len ? k : len - 1)];
        put_lane(&st, k, w->x[e.i], w->y[e.i], w->vx[e.i], w->vy[e.i]);
        SIM_LANE(t[k / SIM_LANES], k % SIM_LANES) = e.t;
    }
    for (int v = 0; v < vectors; v++) {
        sim_vreal x = st.x[v], y = st.y[v], vx = st.vx[v], vy = st.vy[v];
        /* SPEC: move to the wall at t; each axis whose time is t is hit (both at a corner):
         * put on its wall, that velocity component negated. */
        const sim_vmask hx = axis_time_v(x, vx, &c) == t[v];
        const sim_vmask hy = axis_time_v(y, vy, &c) == t[v];
        x = sim_sel(hx, sim_sel(vx > c.zero, c.hi, c.lo), x + t[v] * vx);
        y = sim_sel(hy, sim_sel(vy > c.zero, c.hi, c.lo), y + t[v] * vy);
        vx = sim_sel(hx, -vx, vx);
        vy = sim_sel(hy, -vy, vy);
        finish_v(&x, &y, vx, vy, c.one - t[v], &c);
        st.x[v] = x;
        st.y[v] = y;
        st.vx[v] = vx;
        st.vy[v] = vy;
    }
    for (int k = 0; k < len; k++) {
        take_lane(&st, k, w, nx, ny, events[k0 + (size_t)k].i);
    }
}

void sim_move_pairs(const sim_world *w, const sim_cand *events, size_t count, size_t k0,
                    sim_real *out, sim_real *nx, sim_real *ny)
{
    const lanes_const c = lanes_of(w);
    const int len = block_len(count, k0);
    /* a and b at their contact: positions at t, velocities, and the centre line b - a with
     * its length (the square root in scalar code: vector extensions have none). */
    lanes_state sa, sb;
    sim_vreal t[SIM_EVENT_VECTORS], dx[SIM_EVENT_VECTORS], dy[SIM_EVENT_VECTORS];
    sim_vreal dist[SIM_EVENT_VECTORS];
    const int vectors = (len + SIM_LANES - 1) / SIM_LANES;
    for (int k = 0; k < vectors * SIM_LANES; k++) {
        const sim_cand e = events[k0 + (size_t)(k < len ? k : len - 1)];
        const int32_t a = e.i, b = e.j;
        const sim_real vxa = w->vx[a], vya = w->vy[a], vxb = w->vx[b], vyb = w->vy[b];
        const sim_real xa = w->x[a] + e.t * vxa, ya = w->y[a] + e.t * vya;
        const sim_real xb = w->x[b] + e.t * vxb, yb = w->y[b] + e.t * vyb;
        const sim_real ex = xb - xa, ey = yb - ya;
        put_lane(&sa, k, xa, ya, vxa, vya);
        put_lane(&sb, k, xb, yb, vxb, vyb);
        SIM_LANE(t[k / SIM_LANES], k % SIM_LANES) = e.t;
        SIM_LANE(dx[k / SIM_LANES], k % SIM_LANES) = ex;
        SIM_LANE(dy[k / SIM_LANES], k % SIM_LANES) = ey;
        SIM_LANE(dist[k / SIM_LANES], k % SIM_LANES) = SIM_SQRT(ex * ex + ey * ey);
    }
    for (int v = 0; v < vectors; v++) {
        /* dist is about 2r > 0 at contact; it is 0 only if 2r underflows, and then no normal
         * exists: the discs keep their velocities. */
        const sim_vmask normal = dist[v] > c.zero;
        const sim_vreal ux = dx[v] / dist[v], uy = dy[v] / dist[v];
        const sim_vreal vxa = sa.vx[v], vya = sa.vy[v], vxb = sb.vx[v], vyb = sb.vy[v];
        const sim_vreal ua = vxa * ux + vya * uy;
        const sim_vreal ub = vxb * ux + vyb * uy;
        sa.vx[v] = sim_sel(normal, vxa + (ub - ua) * ux, vxa);
        sa.vy[v] = sim_sel(normal, vya + (ub - ua) * uy, vya);
        sb.vx[v] = sim_sel(normal, vxb + (ua - ub) * ux, vxb);
        sb.vy[v] = sim_sel(normal, vyb + (ua - ub) * uy, vyb);
        const sim_vreal rest = c.one - t[v];
        finish_v(&sa.x[v], &sa.y[v], sa.vx[v], sa.vy[v], rest, &c);
        finish_v(&sb.x[v], &sb.y[v], sb.vx[v], sb.vy[v], rest, &c);
    }
    if (!out) {
        for (int k = 0; k < len; k++) {
            const sim_cand e = events[k0 + (size_t)k];
            take_lane(&sa, k, w, nx, ny, e.i);
            take_lane(&sb, k, w, nx, ny, e.j);
        }
        return;
    }
    for (int k = 0; k < len; k++) {
        sim_real *o = out + SIM_PAIR_OUT * (k0 + (size_t)k);
        const lanes_state *side[2] = {&sa, &sb};
        for (int p = 0; p < 2; p++) {
            o[4 * p] = SIM_LANE(side[p]->x[k / SIM_LANES], k % SIM_LANES);
            o[4 * p + 1] = SIM_LANE(side[p]->y[k / SIM_LANES], k % SIM_LANES);
            o[4 * p + 2] = SIM_LANE(side[p]->vx[k / SIM_LANES], k % SIM_LANES);
            o[4 * p + 3] = SIM_LANE(side[p]->vy[k / SIM_LANES], k % SIM_LANES);
        }
    }
}

size_t sim_event_block(void)
{
    return SIM_EVENT_BLOCK;
}
