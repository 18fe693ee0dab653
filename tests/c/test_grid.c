/*
 * test_grid.c: unit tests of the grid variant (variants/grid.c and its pieces under
 * variants/grid/, linked in; their internal header is included below so that the pieces'
 * helpers can be tested), against the shared all-pairs kernel.
 *
 * Plain C, no framework, as test_core.c: every failed check prints `file:line: what`; the last
 * line is `P passed, F failed` counting test functions; exit status 1 when any failed.
 * `build/tests/test_grid NAME...` runs only the tests whose names contain NAME.
 *
 * The main test builds thousands of small random worlds (slow and fast, sparse and dense,
 * overlapping, on integer lattices so that contact times tie and fall on slice boundaries,
 * huge L, outlier speeds), runs the grid's finder at 1 to 4 threads and checks that it finds
 * exactly the candidates of the all-pairs kernel, with the same t, each once; and the step's
 * slices shared out to several finders (the mpi variant's ranks), which together must find the
 * same.
 */
#include <inttypes.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../../variants/grid/grid.h"
#include "sim_core.h"

#include "check.h"

/* ---- helpers ---- */

#define PI 3.14159265358979323846

static uint64_t rng_state = 12345;

static double uniform(void) /* [0, 1) */
{
    return sim_uniform(&rng_state);
}

static int32_t below(int32_t n) /* [0, n) */
{
    return (int32_t)(uniform() * n);
}

static int cand_cmp_t(const void *pa, const void *pb)
{
    const sim_cand *a = pa, *b = pb;
    if (a->t != b->t)
        return a->t < b->t ? -1 : 1;
    if (a->i != b->i)
        return a->i < b->i ? -1 : 1;
    return (a->j > b->j) - (a->j < b->j);
}

/* A world of n particles in a box of side L, radius r, state left to the caller. */
static void world_make(sim_world *w, int32_t n, double L, double r)
{
    const sim_header h = {.n = n, .L = L, .r = r, .steps = 1, .mode = SIM_MODE_PERF};
    if (sim_world_alloc(w, &h)) {
        fprintf(stderr, "out of memory\n");
        exit(2);
    }
}

static double clamp_to(double v, double lo, double hi)
{
    return v < lo ? lo : v > hi ? hi : v;
}

/* The grid's candidates for the state of w, with `threads` threads and the given scratch
 * (NULL: a fresh one), sorted; *count set. */
/* Cells per box width that grid_candidates forces (0: the finder chooses). */
static int test_sub_force;
/* Whether a team splits every slice into bands whatever N (else small scenes bin every
 * particle in every band). */
static int test_banded;
/* The share of the step's slices grid_candidates looks at: part test_part of test_parts
 * (grid_scratch's slice_part, slice_parts; 1 part: every slice). */
static int test_part, test_parts = 1;

static sim_cand *grid_candidates_with(const sim_world *w, int threads, void *scratch,
                                      size_t *count)
{
    sim_pair_sink sink = {.count = threads, .threads = threads};
    /* The buffers are 64-byte aligned types (a multiple of 64 bytes long, as aligned_alloc
     * needs). */
    sink.bufs = aligned_alloc(_Alignof(sim_cand_buf), (size_t)threads * sizeof *sink.bufs);
    sink.scratch = scratch ? scratch : sim_variant_def.scratch_create(w, threads);
    if (!sink.bufs || !sink.scratch) {
        fprintf(stderr, "out of memory\n");
        exit(2);
    }
    memset(sink.bufs, 0, (size_t)threads * sizeof *sink.bufs);
    ((grid_scratch *)sink.scratch)->sub_force = test_sub_force;
    ((grid_scratch *)sink.scratch)->slice_part = test_part;
    ((grid_scratch *)sink.scratch)->slice_parts = test_parts;
    if (test_banded)
        ((grid_scratch *)sink.scratch)->direct_n = 0;
    sim_variant_def.find_pairs(w, &sink);
    size_t total = 0;
    for (int k = 0; k < threads; k++) {
        CHECK(!sink.bufs[k].failed);
        total += sink.bufs[k].len;
    }
    sim_cand *all = malloc((total + 1) * sizeof *all);
    size_t at = 0;
    for (int k = 0; k < threads; k++) {
        if (sink.bufs[k].len)
            memcpy(all + at, sink.bufs[k].items, sink.bufs[k].len * sizeof *all);
        at += sink.bufs[k].len;
        free(sink.bufs[k].items);
    }
    if (!scratch)
        sim_variant_def.scratch_destroy(sink.scratch);
    free(sink.bufs);
    qsort(all, total, sizeof *all, cand_cmp_t);
    *count = total;
    return all;
}

static sim_cand *grid_candidates(const sim_world *w, int threads, size_t *count)
{
    return grid_candidates_with(w, threads, NULL, count);
}

/* The candidates of every part of the step's slices shared out to `parts` finders (the mpi
 * variant's ranks), together, sorted; one scratch a part (NULL: fresh ones). */
static sim_cand *shared_candidates(const sim_world *w, int threads, int parts, void **scratch,
                                   size_t *count)
{
    sim_cand *all = NULL;
    size_t total = 0;
    test_parts = parts;
    for (test_part = 0; test_part < parts; test_part++) {
        size_t n;
        sim_cand *got = grid_candidates_with(w, threads, scratch ? scratch[test_part] : NULL, &n);
        all = realloc(all, (total + n + 1) * sizeof *all);
        if (!all) {
            fprintf(stderr, "out of memory\n");
            exit(2);
        }
        memcpy(all + total, got, n * sizeof *all);
        total += n;
        free(got);
    }
    test_part = 0, test_parts = 1;
    qsort(all, total, sizeof *all, cand_cmp_t);
    *count = total;
    return all;
}

/* Exactly the same list, t bit for bit? */
static int same_candidates(const sim_cand *a, size_t na, const sim_cand *b, size_t nb)
{
    if (na != nb)
        return 0;
    for (size_t k = 0; k < na; k++)
        if (a[k].i != b[k].i || a[k].j != b[k].j || memcmp(&a[k].t, &b[k].t, sizeof a[k].t))
            return 0;
    return 1;
}

/* The all-pairs kernel's candidates, sorted. */
static sim_cand *reference_candidates(const sim_world *w, size_t *count)
{
    sim_cand_buf buf = {0};
    for (int32_t i = 0; i < w->n; i++)
        sim_scan_full_row(w, i, &buf);
    CHECK(!buf.failed);
    if (buf.len)
        qsort(buf.items, buf.len, sizeof *buf.items, cand_cmp_t);
    *count = buf.len;
    return buf.items ? buf.items : calloc(1, sizeof(sim_cand));
}

/* Does the grid find exactly the reference's candidates, at 1..4 and 8 threads? Returns the
 * number of candidates (for the callers' statistics). */
static size_t check_world(const sim_world *w, const char *what)
{
    size_t nref;
    sim_cand *ref = reference_candidates(w, &nref);
    /* Every thread count, with the cells the finder chooses and with each subdivision forced
     * (sub 1 .. GRID_SUB_MAX), whatever the scene would get; a team both ways (every particle
     * binned in every band, and split into bands); 8 threads give bands a row or two high. */
    for (int sub = 0; sub <= GRID_SUB_MAX; sub++)
        for (int threads = 1; threads <= 8; threads += threads < 4 ? 1 : 4)
            for (int banded = 0; banded <= (threads > 1); banded++) {
                size_t ngot;
                test_sub_force = sub;
                test_banded = banded;
                sim_cand *got = grid_candidates(w, threads, &ngot);
                test_sub_force = 0;
                test_banded = 0;
                if (!same_candidates(got, ngot, ref, nref)) {
                    fail_at(__FILE__, __LINE__, "%s (n=%d L=%g r=%g, %d threads, sub %d, %s): "
                            "%zu candidates, expected %zu", what, w->n, (double)w->L,
                            (double)w->r, threads, sub, banded ? "banded" : "direct", ngot,
                            nref);
                    free(got);
                    sub = GRID_SUB_MAX;
                    threads = 8;
                    break;
                }
                free(got);
            }
    /* The slices shared out (K rounded to a multiple of the parts where it can be, some parts
     * with none where it cannot): the parts together find the same candidates, each once. */
    static const int shares[][3] = {{2, 1, 0}, {3, 2, 1}, {4, 2, 0}}; /* parts, threads, banded */
    for (size_t c = 0; c < sizeof shares / sizeof shares[0]; c++) {
        size_t ngot;
        test_banded = shares[c][2];
        sim_cand *got = shared_candidates(w, shares[c][1], shares[c][0], NULL, &ngot);
        test_banded = 0;
        if (!same_candidates(got, ngot, ref, nref))
            fail_at(__FILE__, __LINE__, "%s (n=%d L=%g r=%g): %d parts of the slices on %d "
                    "threads found %zu candidates, expected %zu", what, w->n, (double)w->L,
                    (double)w->r, shares[c][0], shares[c][1], ngot, nref);
        free(got);
    }
    free(ref);
    return nref;
}

/* ---- the tests ---- */

/* Swapping the two particles negates every input of the slice test exactly: same answer. */
static void test_near_is_symmetric(void)
{
    for (int k = 0; k < 200000; k++) {
        const double s = pow(10, 6 * uniform() - 3);
        const double dx = s * (2 * uniform() - 1), dy = s * (2 * uniform() - 1);
        const double ddx = s * (2 * uniform() - 1), ddy = s * (2 * uniform() - 1);
        const double t0 = below(8) / 8.0, t1 = t0 + 0.125, r2 = s * s * uniform();
        CHECK_INT(near_in_slice(dx, dy, ddx, ddy, t0, t1, r2),
                  near_in_slice(-dx, -dy, -ddx, -ddy, t0, t1, r2));
    }
}

/* The cell of a coordinate never decreases as the coordinate grows, infinities included, and
 * stays within [0, top]. */
static void test_cell_is_monotone(void)
{
    const float inv_h[] = {1.0f / 3, 1e-7f, 1e7f, 0};
    for (size_t m = 0; m < sizeof inv_h / sizeof inv_h[0]; m++)
        for (int k = 0; k < 100000; k++) {
            float a = (float)((2 * uniform() - 1) * pow(10, 12 * uniform()));
            float b = a + (float)(uniform() * 10);
            if (k % 1000 == 0)
                a = -HUGE_VALF;
            if (k % 1000 == 1)
                b = HUGE_VALF;
            const int32_t ca = cell_of(a, inv_h[m], 1000), cb = cell_of(b, inv_h[m], 1000);
            CHECK(ca <= cb);
            CHECK(ca >= 0 && cb <= 1000);
        }
}

/* The two facts the float binning rests on, for pairs built to pass within 2r + delta * u
 * (u in [0, 1]: up to the edge of "near") at a chosen time, in scenes from L = 10 to 10^7: in
 * every slice where the pair is near (in double), the float prefilter passes it and the float
 * boxes' cell ranges intersect. */
static void test_near_pairs_pass_the_float_binning(void)
{
    const int ks[] = {1, 3, 8, 64, 1000};
    sim_world w;
    world_make(&w, 3, 10, 1);
    void *scratch = sim_variant_def.scratch_create(&w, 1);
    grid_scratch *s = scratch;
    int near_slices = 0;
    for (int trial = 0; trial < 20000; trial++) {
        const double L = pow(10, 1 + 6 * uniform()), r = 0.5 + uniform();
        w.L = (sim_real)L, w.r = (sim_real)r;
        const double speed = L * pow(10, -4 * uniform()), tc = trial % 2 ? below(9) / 8.0 : uniform();
        const double phi = 2 * PI * uniform(), psi = 2 * PI * uniform();
        /* Particle 2 only sets the extent: somewhere in the box. */
        w.x[2] = (sim_real)(L * uniform()), w.y[2] = (sim_real)(L * uniform());
        w.vx[2] = w.vy[2] = 0;
        const double cx = L * uniform(), cy = L * uniform();
        const double vax = speed * (2 * uniform() - 1), vay = speed * (2 * uniform() - 1);
        const double vbx = speed * cos(psi), vby = speed * sin(psi);
        w.x[0] = (sim_real)(cx - tc * vax), w.y[0] = (sim_real)(cy - tc * vay);
        w.vx[0] = (sim_real)vax, w.vy[0] = (sim_real)vay;
        grid_plan g;
        grid_plan_step(&w, s, &g, 1); /* for delta: the separation needs it */
        const double delta = sqrt(g.reach2) - 2 * r;
        const double sep = 2 * r + delta * uniform();
        w.x[1] = (sim_real)(cx + sep * cos(phi) - tc * vbx);
        w.y[1] = (sim_real)(cy + sep * sin(phi) - tc * vby);
        w.vx[1] = (sim_real)vbx, w.vy[1] = (sim_real)vby;
        grid_plan_step(&w, s, &g, 1);
        for (size_t m = 0; m < sizeof ks / sizeof ks[0]; m++) {
            g.K = ks[m];
            for (int k = 0; k <= g.K; k++)
                s->tk[k] = (double)k / g.K;
            float b[2][4];
            for (int i = 0; i < 2; i++) {
                const grid_particle q = grid_part(&w, i);
                particle_f32(&q, &g, &b[i][0], &b[i][1], &b[i][2], &b[i][3]);
            }
            for (int k = 0; k < g.K; k++) {
                if (!near_pair(&w, s->tk, g.reach2, 0, 1, k))
                    continue;
                near_slices++;
                const float kf = (float)k;
                float p[2][2];
                int32_t lo[2][2], hi[2][2];
                for (int i = 0; i < 2; i++)
                    for (int ax = 0; ax < 2; ax++) {
                        p[i][ax] = slice_start(b[i][ax], b[i][2 + ax], kf);
                        axis_cells(p[i][ax], b[i][2 + ax], g.rpad, g.inv_h,
                                   ax ? g.topy : g.topx, &lo[i][ax], &hi[i][ax]);
                    }
                const grid_vf px = {p[1][0] - p[0][0]}, py = {p[1][1] - p[0][1]};
                const grid_vf wx = {b[1][2] - b[0][2]}, wy = {b[1][3] - b[0][3]};
                if (!(near_f32(px, py, wx, wy, g.freach2, g.fend) &
                      near_f32_line(px, py, wx, wy, g.freach2, g.fend) & 1))
                    fail_at(__FILE__, __LINE__, "near pair (L=%g, K=%d, k=%d) fails the prefilter",
                            L, g.K, k);
                for (int ax = 0; ax < 2; ax++)
                    if (lo[0][ax] > hi[1][ax] || lo[1][ax] > hi[0][ax])
                        fail_at(__FILE__, __LINE__, "near pair (L=%g, K=%d, k=%d): float boxes "
                                "apart on axis %d", L, g.K, k, ax);
            }
        }
    }
    CHECK(near_slices > 20000);
    sim_variant_def.scratch_destroy(scratch);
    sim_world_free(&w);
}

/* near_f32 and near_f32_line on their own, lane by lane, against the segment distance in
 * double: relative segments from p to p + w (|w| up to the slice's longest) built to pass
 * within R (1 - 1e-4) of the origin at an end, inside, or standing still (w == 0) must pass
 * both; lines that pass further than 1.01 times the padded reach from the origin must pass
 * neither, and still pairs beyond it must fail near_f32 (the line test passes them). The
 * far end q = p + w is tested without its own distance (near_f32's comment), so the "at q"
 * cases are the ones a wrong end slack would lose. */
static void test_prefilter_passes_near_and_rejects_far_segments(void)
{
    int passed_near = 0, rejected_far = 0;
    for (int trial = 0; trial < 200000; trial++) {
        const double R = pow(10, 3 * uniform() - 1), wmax = R * pow(10, 4 * uniform());
        /* The reach with a float margin in the plan's style (grid_plan_step): the floats here are
         * up to 2 wmax + R in magnitude. */
        const double Rf = R + GRID_F32_MARGIN * (double)FLT_EPSILON * 4 * (2 * wmax + R);
        const float r2 = (float)(Rf * Rf * (1 + 8 * (double)FLT_EPSILON));
        const float tend = (float)(Rf * wmax * (1 + 64 * (double)FLT_EPSILON));
        const double phi = 2 * PI * uniform(), wl = trial % 7 ? wmax * uniform() : 0;
        const double ux = cos(phi), uy = sin(phi); /* w's direction */
        double px, py;
        const int kind = trial % 4;
        if (kind < 3) { /* near: the closest point at p (0), inside (1) or at q (2) */
            const double d = R * (1 - 1e-4) * uniform(), psi = 2 * PI * uniform();
            const double cx = d * cos(psi), cy = d * sin(psi); /* the closest point */
            const double s = kind == 0 ? 0 : kind == 1 ? uniform() : 1;
            px = cx - s * wl * ux, py = cy - s * wl * uy;
        } else { /* far: the whole line at distance in (1.01 Rf, 10 Rf); w == 0: p beyond */
            const double d = Rf * (1.01 + 9 * uniform()), s = 3 * uniform() - 1;
            px = -d * uy - s * wl * ux, py = d * ux - s * wl * uy;
            if (wl == 0)
                px = Rf * (1.01 + uniform()), py = 0;
        }
        grid_vf vpx = {0}, vpy = {0}, vwx = {0}, vwy = {0};
        const int l = trial % GRID_LANES; /* every lane in turn; the others far apart */
        for (int m = 0; m < GRID_LANES; m++)
            vpx[m] = (float)(1e3 * R), vwx[m] = (float)(wmax / 2);
        vpx[l] = (float)px, vpy[l] = (float)py, vwx[l] = (float)(wl * ux), vwy[l] = (float)(wl * uy);
        const uint32_t got = near_f32(vpx, vpy, vwx, vwy, r2, tend);
        const uint32_t line = near_f32_line(vpx, vpy, vwx, vwy, r2, tend);
        for (int m = 0; m < GRID_LANES; m++)
            if (m != l && (got | line) >> m & 1)
                fail_at(__FILE__, __LINE__, "lane %d: a pair 1000 R apart passed", m);
        if (kind < 3 && !(got >> l & 1))
            fail_at(__FILE__, __LINE__, "near segment (kind %d, R=%g, |w|=%g) rejected", kind, R, wl);
        /* The runs pass a pair on only if near_f32_line passes it too. */
        if (kind < 3 && !(line >> l & 1))
            fail_at(__FILE__, __LINE__, "near segment (kind %d, R=%g, |w|=%g) fails the line test",
                    kind, R, wl);
        if (kind == 3 && got >> l & 1)
            fail_at(__FILE__, __LINE__, "far segment (R=%g, |w|=%g) passed", R, wl);
        /* The line test alone passes still pairs (w == 0) at any distance, not moving ones. */
        if (kind == 3 && (line >> l & 1) != (wl == 0))
            fail_at(__FILE__, __LINE__, "far segment (R=%g, |w|=%g): line test %d", R, wl,
                    (int)(line >> l & 1));
        passed_near += kind < 3 && got >> l & 1;
        rejected_far += kind == 3 && !(got >> l & 1);
    }
    CHECK(passed_near == 150000 && rejected_far == 50000);
}

/* Scenes floats cannot carry (speeds of 1e300, 1e200, coordinates of 1e30): the plan turns
 * the floats off, and the zeros every entry then holds pass both prefilter tests, so every
 * pair goes to the double test. */
static void test_prefilter_passes_everything_where_floats_are_off(void)
{
    const double speeds[] = {1e300, 1e200, 1e30};
    sim_world w;
    world_make(&w, 3, 1000, 1);
    void *scratch = sim_variant_def.scratch_create(&w, 1);
    grid_scratch *s = scratch;
    for (size_t m = 0; m < sizeof speeds / sizeof speeds[0]; m++) {
        for (int i = 0; i < 3; i++)
            w.x[i] = (sim_real)(100 + 300 * i), w.y[i] = 500;
        w.vx[0] = (sim_real)speeds[m], w.vy[1] = (sim_real)-speeds[m];
        grid_plan g;
        grid_plan_step(&w, s, &g, 1);
        CHECK(g.f32_off);
        float b[4];
        const grid_particle q = grid_part(&w, 0);
        particle_f32(&q, &g, &b[0], &b[1], &b[2], &b[3]);
        CHECK(b[0] == 0 && b[1] == 0 && b[2] == 0 && b[3] == 0);
        const grid_vf zero = {0};
        const uint32_t all = (uint32_t)(((uint64_t)1 << GRID_LANES) - 1);
        CHECK(near_f32(zero, zero, zero, zero, g.freach2, g.fend) == all);
        CHECK(near_f32_line(zero, zero, zero, zero, g.freach2, g.fend) == all);
    }
    sim_variant_def.scratch_destroy(scratch);
    sim_world_free(&w);
}

/* Every pair the kernel accepts is near in some slice, whatever K: built to meet at a chosen
 * time, often exactly on a slice boundary, head-on, oblique or grazing (tangent). */
static void test_accepted_pairs_are_near_in_some_slice(void)
{
    const int ks[] = {1, 2, 3, 4, 7, 8, 16, 64, 250, 4096};
    sim_world w;
    world_make(&w, 2, 1000, 1);
    void *scratch = sim_variant_def.scratch_create(&w, 1);
    grid_scratch *s = scratch;
    int accepted = 0;
    for (int trial = 0; trial < 20000; trial++) {
        /* Contact at time tc with the line of centres at angle phi; relative velocity at angle
         * psi from the normal (|psi| close to 90 degrees: grazing). */
        const double tc = trial % 3 ? below(9) / 8.0 : uniform();
        const double phi = 2 * PI * uniform();
        const double psi = (trial % 5 == 0 ? 0.5 * PI * (1 - 1e-9 * uniform())
                                           : 0.5 * PI * (2 * uniform() - 1));
        const double speed = pow(10, 4 * uniform() - 1);
        const double nx = cos(phi), ny = sin(phi);
        const double dvx = -speed * (nx * cos(psi) - ny * sin(psi));
        const double dvy = -speed * (ny * cos(psi) + nx * sin(psi));
        const double cx = 500, cy = 500, vx0 = 100 * (2 * uniform() - 1);
        const double vy0 = 100 * (2 * uniform() - 1);
        w.x[0] = cx - tc * vx0, w.y[0] = cy - tc * vy0, w.vx[0] = vx0, w.vy[0] = vy0;
        w.x[1] = cx + 2 * nx - tc * (vx0 + dvx), w.y[1] = cy + 2 * ny - tc * (vy0 + dvy);
        w.vx[1] = vx0 + dvx, w.vy[1] = vy0 + dvy;
        sim_real t;
        if (!sim_pair_time(&w, 0, 1, &t))
            continue;
        accepted++;
        grid_plan g;
        grid_plan_step(&w, s, &g, 1);
        for (size_t m = 0; m < sizeof ks / sizeof ks[0]; m++) {
            for (int k = 0; k <= ks[m]; k++)
                s->tk[k] = (double)k / ks[m];
            int near = 0;
            for (int k = 0; k < ks[m] && !near; k++)
                near = near_pair(&w, s->tk, g.reach2, 0, 1, k);
            if (!near)
                fail_at(__FILE__, __LINE__, "accepted pair (t=%.17g) near in no slice of %d",
                        (double)t, ks[m]);
        }
    }
    CHECK(accepted > 5000);
    sim_variant_def.scratch_destroy(scratch);
    sim_world_free(&w);
}

/* Worlds of the main test. The ASan+UBSan build runs each several times slower: it checks
 * half of them, still each kind 50 times at every thread count and subdivision; so does the
 * portable build (TEST_PORTABLE), whose teams and subdivisions are the same C code as the
 * optimised build's, and whose numeric loops half the worlds run through every kind; the
 * optimised build checks them all. */
#if defined(__SANITIZE_ADDRESS__) || defined(TEST_PORTABLE)
#define ALL_PAIRS_WORLDS 300
#else
#define ALL_PAIRS_WORLDS 600
#endif

/* The main test: random worlds of every kind, the grid against all pairs. */
static void test_finds_exactly_the_all_pairs_candidates(void)
{
    size_t candidates = 0;
    for (int trial = 0; trial < ALL_PAIRS_WORLDS; trial++) {
        const int kind = trial % 6;
        const int32_t n = kind == 5 ? 2 + below(6) : below(300);
        const double L = kind == 3 ? 1e7 : pow(10, 1 + 2.5 * uniform());
        const double r = kind == 4 ? 0.25 * L / (1 + n) : 0.5 + uniform();
        if (2 * r > L)
            continue;
        sim_world w;
        world_make(&w, n, L, r);
        for (int32_t i = 0; i < n; i++) {
            double x = r + uniform() * (L - 2 * r), y = r + uniform() * (L - 2 * r);
            double speed;
            switch (kind) {
            case 0: /* slow: |v| ~ r */
                speed = r * (0.5 + uniform());
                break;
            case 1: /* the report's: L/8r .. L/4 */
                speed = L / 8 + uniform() * L / 8;
                break;
            case 2: /* mixed, outliers */
                speed = pow(10, 6 * uniform() - 3) * (i % 17 == 0 ? 1e4 : 1);
                break;
            case 3: /* huge L, slow */
                speed = 1 + uniform();
                break;
            default: /* integer lattice: ties and contact times on slice boundaries */
                x = clamp_to(r + 2 * r * below((int32_t)(L / (2 * r))), r, L - r);
                y = clamp_to(r + 2 * r * below((int32_t)(L / (2 * r))), r, L - r);
                speed = r * (1 + below(4));
                break;
            }
            const double a = kind >= 4 ? 0.5 * PI * below(4) : 2 * PI * uniform();
            w.x[i] = x, w.y[i] = y;
            w.vx[i] = speed * cos(a), w.vy[i] = speed * sin(a);
            if (kind >= 4) /* axis-aligned, exactly */
                w.vx[i] = round(w.vx[i]), w.vy[i] = round(w.vy[i]);
        }
        char what[64];
        snprintf(what, sizeof what, "trial %d kind %d", trial, kind);
        candidates += check_world(&w, what);
        sim_world_free(&w);
    }
    CHECK(candidates > 1000);
}

/* Hand-built: every pair of a row meets exactly at t = 1/2 (slice boundary for even K), with
 * contact points on a regular lattice; and discs resting in contact (t = 0 or never). */
static void test_ties_on_boundaries(void)
{
    sim_world w;
    world_make(&w, 400, 400, 1);
    for (int32_t i = 0; i < 400; i++) {
        const int32_t gx = i % 20, gy = i / 20;
        w.x[i] = 10 + 19 * gx + (gx % 2 ? 0 : 2), w.y[i] = 10 + 19 * gy;
        w.vx[i] = gx % 2 ? -2 : 2, w.vy[i] = gy % 3 == 0 ? 0 : gy % 3 == 1 ? 17.5 : -17.5;
    }
    check_world(&w, "lattice ties");
    for (int32_t i = 0; i < 400; i++) {
        w.x[i] = 2 + 2 * (i % 100), w.y[i] = 2 + 2 * (i / 100);
        w.vx[i] = i % 2 ? -1 : 1, w.vy[i] = 0;
    }
    check_world(&w, "resting contacts");
    sim_world_free(&w);
}

/* One scratch through many steps, as in a run (it keeps the particles' order from step to
 * step): the candidates must still be exactly the all-pairs ones. */
static void test_repeated_steps_on_one_scratch(void)
{
    for (int threads = 1; threads <= 3; threads++) {
        sim_world w;
        world_make(&w, 3000, 500, 1);
        for (int32_t i = 0; i < w.n; i++) {
            w.x[i] = 1 + uniform() * 498, w.y[i] = 1 + uniform() * 498;
            const double a = 2 * PI * uniform(), sp = 20 + 40 * uniform();
            w.vx[i] = sp * cos(a), w.vy[i] = sp * sin(a);
        }
        void *scratch = sim_variant_def.scratch_create(&w, threads);
        sim_stepper *st = sim_stepper_create(&w, &sim_variant_def, 1);
        sim_stats stats = {0};
        for (int step = 0; step < 5; step++) {
            size_t nref, ngot;
            sim_cand *ref = reference_candidates(&w, &nref);
            sim_cand *got = grid_candidates_with(&w, threads, scratch, &ngot);
            if (!same_candidates(got, ngot, ref, nref))
                fail_at(__FILE__, __LINE__, "step %d, %d threads: %zu candidates, expected %zu",
                        step, threads, ngot, nref);
            free(ref);
            free(got);
            CHECK(sim_step(st, &w, &stats) == 0);
        }
        sim_stepper_destroy(st);
        sim_variant_def.scratch_destroy(scratch);
        sim_world_free(&w);
    }
}

/* The slices shared out to 3 parts, each with a scratch of its own through many steps (each
 * keeps its own order from step to step), fast (K a multiple of 3) and slow (K = 1: two parts
 * have no slice and keep the order as it is): together, the all-pairs candidates. */
static void test_shared_slices_through_steps(void)
{
    enum { PARTS = 3 };
    for (int slow = 0; slow <= 1; slow++) {
        sim_world w;
        world_make(&w, 3000, 500, 1);
        for (int32_t i = 0; i < w.n; i++) {
            w.x[i] = 1 + uniform() * 498, w.y[i] = 1 + uniform() * 498;
            const double a = 2 * PI * uniform(), sp = slow ? 0.5 + uniform() : 20 + 40 * uniform();
            w.vx[i] = sp * cos(a), w.vy[i] = sp * sin(a);
        }
        void *scratch[PARTS];
        for (int p = 0; p < PARTS; p++)
            scratch[p] = sim_variant_def.scratch_create(&w, 2);
        sim_stepper *st = sim_stepper_create(&w, &sim_variant_def, 1);
        sim_stats stats = {0};
        for (int step = 0; step < 5; step++) {
            size_t nref, ngot;
            sim_cand *ref = reference_candidates(&w, &nref);
            sim_cand *got = shared_candidates(&w, 2, PARTS, scratch, &ngot);
            if (!same_candidates(got, ngot, ref, nref))
                fail_at(__FILE__, __LINE__, "%s, step %d: %zu candidates, expected %zu",
                        slow ? "slow" : "fast", step, ngot, nref);
            free(ref);
            free(got);
            CHECK(sim_step(st, &w, &stats) == 0);
        }
        sim_stepper_destroy(st);
        for (int p = 0; p < PARTS; p++)
            sim_variant_def.scratch_destroy(scratch[p]);
        sim_world_free(&w);
    }
}

static const test_case tests[] = {
    {"near_is_symmetric", test_near_is_symmetric},
    {"prefilter_passes_near_and_rejects_far_segments",
     test_prefilter_passes_near_and_rejects_far_segments},
    {"prefilter_passes_everything_where_floats_are_off",
     test_prefilter_passes_everything_where_floats_are_off},
    {"cell_is_monotone", test_cell_is_monotone},
    {"near_pairs_pass_the_float_binning", test_near_pairs_pass_the_float_binning},
    {"accepted_pairs_are_near_in_some_slice", test_accepted_pairs_are_near_in_some_slice},
    {"finds_exactly_the_all_pairs_candidates", test_finds_exactly_the_all_pairs_candidates},
    {"ties_on_boundaries", test_ties_on_boundaries},
    {"repeated_steps_on_one_scratch", test_repeated_steps_on_one_scratch},
    {"shared_slices_through_steps", test_shared_slices_through_steps},
};

int main(int argc, char **argv)
{
    return run_tests(tests, TEST_COUNT(tests), argc, argv);
}
