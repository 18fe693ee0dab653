/*
 * test_core.c: unit tests of the shared simulation core (variants/core), against the model (docs/model.md).
 *
 * Plain C, no framework. Every failed check prints one line `file:line: what (values)`; the
 * last line is `P passed, F failed` counting test functions; the exit status is 1 when any
 * test failed. `build/tests/test_core NAME...` runs only the tests whose names contain NAME.
 *
 * The tests that step a world use this file's own all-pairs finder (sim_variant_def below) and
 * a second finder that finds the same pairs in reverse order into several buffers.
 */
#define _GNU_SOURCE /* sched_getaffinity and the CPU_* macros, for the team test */
#include <inttypes.h>
#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#if defined(__linux__)
#include <sched.h>
#endif

#include "sim_core.h"

#include "check.h"

/* ---- finders for the stepper ---- */

/* Every pair i < j, forwards, one buffer: what seq does. */
static void find_all_pairs(const sim_world *w, sim_pair_sink *sink)
{
    for (int32_t i = 0; i < w->n; i++)
        sim_scan_row(w, i, i + 1, w->n, sim_sink_buf(sink, 0));
}

const sim_variant sim_variant_def = {
    .name = "test",
    .summary = "every pair i < j, forwards, one buffer",
    .exact = true,
    .parallel = false,
    .all_pairs = true,
    .find_pairs = find_all_pairs,
};

/* The same pairs found backwards and spread over three buffers: the step must not care. */
static int three_buffers(int threads)
{
    (void)threads;
    return 3;
}

static void find_pairs_reversed(const sim_world *w, sim_pair_sink *sink)
{
    for (int32_t i = w->n - 1; i >= 0; i--)
        for (int32_t j = w->n - 1; j > i; j--) {
            sim_cand_buf *buf = sim_sink_buf(sink, (int)((i + 2 * j) % sink->count));
            sim_real t;
            buf->pair_tests++;
            if (sim_pair_time(w, i, j, &t))
                sim_cand_push(buf, t, i, j);
        }
}

static const sim_variant reversed_variant = {
    .name = "reversed",
    .exact = true,
    .parallel = false,
    .buffer_count = three_buffers,
    .find_pairs = find_pairs_reversed,
};

/* ---- helpers ---- */

static sim_header header(int32_t n, double L, double r, int64_t steps)
{
    return (sim_header){.n = n, .L = L, .r = r, .steps = steps, .mode = SIM_MODE_PERF};
}

/* A world of n particles all at rest at the centre; the test places them. */
static void world_init(sim_world *w, int32_t n, double L, double r)
{
    const sim_header h = header(n, L, r, 1);
    if (sim_world_alloc(w, &h) != 0) {
        fprintf(stderr, "test_core: out of memory\n");
        exit(1);
    }
    for (int32_t i = 0; i < n; i++) {
        w->x[i] = w->y[i] = L / 2;
        w->vx[i] = w->vy[i] = 0;
    }
}

static void put(sim_world *w, int32_t i, double x, double y, double vx, double vy)
{
    w->x[i] = x;
    w->y[i] = y;
    w->vx[i] = vx;
    w->vy[i] = vy;
}

/* Advance `steps` steps with variant v; stats accumulate into *st when given. */
static void run_steps(sim_world *w, const sim_variant *v, int steps, sim_stats *st)
{
    sim_stats local = {0};
    sim_stepper *s = sim_stepper_create(w, v, 1);
    if (!s) {
        fprintf(stderr, "test_core: out of memory\n");
        exit(1);
    }
    for (int k = 0; k < steps; k++)
        if (sim_step(s, w, st ? st : &local) != 0) {
            fprintf(stderr, "test_core: sim_step failed\n");
            exit(1);
        }
    sim_stepper_destroy(s);
}

/* A test-local generator (not the core's), so scenes do not depend on the code under test. */
static uint64_t rng_state = 0x2545F4914F6CDD1DULL;
static double rnd(void) /* uniform [0, 1) from xorshift64* */
{
    rng_state ^= rng_state >> 12;
    rng_state ^= rng_state << 25;
    rng_state ^= rng_state >> 27;
    return (double)((rng_state * 0x2545F4914F6CDD1DULL) >> 11) * 0x1p-53;
}

/* Kinetic energy, as sum of |v|^2 (the factor m/2 is common to all particles). */
static double energy(const sim_world *w)
{
    double e = 0;
    for (int32_t i = 0; i < w->n; i++)
        e += w->vx[i] * w->vx[i] + w->vy[i] * w->vy[i];
    return e;
}

/* ---- the generator (SPEC §4) ---- */

/* Expected values computed independently with Python's integers:
 *   python3 -c 'M=(1<<64)-1
 *   def g(s,n):
 *    o=[]
 *    for _ in range(n):
 *     s=(s+0x9E3779B97F4A7C15)&M; z=s; z=((z^(z>>30))*0xBF58476D1CE4E5B9)&M
 *     z=((z^(z>>27))*0x94D049BB133111EB)&M; o.append(z^(z>>31))
 *    return o
 *   for s in (1,0,M): print([hex(v) for v in g(s,8)])'
 * (0xe220a8397b1dcdaf, the first value for seed 0, is also the published splitmix64 vector.) */
static void test_splitmix64_seed1(void)
{
    static const uint64_t want[8] = {
        UINT64_C(0x910a2dec89025cc1), UINT64_C(0xbeeb8da1658eec67),
        UINT64_C(0xf893a2eefb32555e), UINT64_C(0x71c18690ee42c90b),
        UINT64_C(0x71bb54d8d101b5b9), UINT64_C(0xc34d0bff90150280),
        UINT64_C(0xe099ec6cd7363ca5), UINT64_C(0x85e7bb0f12278575),
    };
    uint64_t state = 1;
    for (int k = 0; k < 8; k++) {
        CHECK_U64(sim_splitmix64_next(&state), want[k]);
        /* The state advances by the golden gamma, modulo 2^64. */
        CHECK_U64(state, 1 + (uint64_t)(k + 1) * UINT64_C(0x9E3779B97F4A7C15));
    }
}

static void test_splitmix64_seed0_and_wraparound(void)
{
    static const uint64_t want0[4] = {
        UINT64_C(0xe220a8397b1dcdaf), UINT64_C(0x6e789e6aa1b965f4),
        UINT64_C(0x06c45d188009454f), UINT64_C(0xf88bb8a8724c81ec),
    };
    static const uint64_t want_max[4] = {
        UINT64_C(0xe4d971771b652c20), UINT64_C(0xe99ff867dbf682c9),
        UINT64_C(0x382ff84cb27281e9), UINT64_C(0x6d1db36ccba982d2),
    };
    uint64_t s0 = 0, smax = UINT64_MAX;
    for (int k = 0; k < 4; k++) {
        CHECK_U64(sim_splitmix64_next(&s0), want0[k]);
        CHECK_U64(sim_splitmix64_next(&smax), want_max[k]);
    }
}

/* u = (next >> 11) * 2^-53; the hex values are Python's float.hex() of the same expression. */
static void test_uniform_seed1(void)
{
    static const double want[4] = {
        0x1.22145bd91204bp-1, 0x1.7dd71b42cb1ddp-1, 0x1.f12745ddf664ap-1, 0x1.c7061a43b90b2p-2,
    };
    uint64_t state = 1;
    for (int k = 0; k < 4; k++)
        CHECK_REAL(sim_uniform(&state), want[k]);
    /* Always in [0, 1), over many draws. */
    state = 12345;
    int outside = 0;
    for (int k = 0; k < 100000; k++) {
        const double u = sim_uniform(&state);
        outside += !(u >= 0 && u < 1);
    }
    CHECK_INT(outside, 0);
}

/* The first three particles for seed 1, L = 100, r = 1 (speeds in [12.5, 25]), from Python:
 * x = 1 + 98*u1, y = 1 + 98*u2 (exact, same IEEE operations), speed = 12.5 + u3*12.5,
 * angle = 2*pi*u4, vx = speed*cos(angle), vy = speed*sin(angle). The cos/sin come from a libm,
 * so the velocities are compared to 4 ulps, the positions exactly. */
static const double gen_seed1[3][4] = {
    {0x1.c42f2ca463973p+5, 0x1.2858b0df2382dp+6, -0x1.725ae7a3d6ff9p+4, 0x1.0e0bb60817c96p+3},
    {0x1.644db3d800153p+5, 0x1.2f0dfa5f54a02p+6, -0x1.7388748c8627bp+4, -0x1.b1d402c42a75ep+1},
    {0x1.cfad785107a51p+4, 0x1.3b3f25ba22352p+6, -0x1.bae29cee5fbdfp+3, -0x1.596a184262245p+3},
};

static void check_particle(const sim_world *w, int32_t i, const double want[4], int line)
{
    const int before = checks_failed;
    CHECK_REAL(w->x[i], want[0]);
    CHECK_REAL(w->y[i], want[1]);
    CHECK_NEAR(w->vx[i], want[2], 4 * 0x1p-52 * fabs(want[2]));
    CHECK_NEAR(w->vy[i], want[3], 4 * 0x1p-52 * fabs(want[3]));
    if (checks_failed != before)
        printf("  (particle %ld, checked from line %d)\n", (long)i, line);
}

static void test_generate_seed1(void)
{
    sim_world w;
    const sim_header h = header(3, 100, 1, 0);
    CHECK_INT(sim_world_alloc(&w, &h), 0);
    unsigned char listed[4] = {0};
    sim_generate(&w, &h, listed, 1);
    for (int32_t i = 0; i < 3; i++)
        check_particle(&w, i, gen_seed1[i], __LINE__);
    sim_world_free(&w);
}

/* Listed particles keep their values and take no draws: particle 2 gets particle 1's draws. */
static void test_generate_skips_listed(void)
{
    sim_world w;
    const sim_header h = header(3, 100, 1, 0);
    CHECK_INT(sim_world_alloc(&w, &h), 0);
    unsigned char listed[4] = {0, 1, 0, 0};
    put(&w, 1, 50, 60, 0.5, -0.25);
    sim_generate(&w, &h, listed, 1);
    check_particle(&w, 0, gen_seed1[0], __LINE__);
    check_particle(&w, 2, gen_seed1[1], __LINE__);
    CHECK_REAL(w.x[1], 50);
    CHECK_REAL(w.y[1], 60);
    CHECK_REAL(w.vx[1], 0.5);
    CHECK_REAL(w.vy[1], -0.25);
    sim_world_free(&w);
}

/* Every generated particle lies in [r, L-r] and has a speed in [min, max] of L/(8r), L/4,
 * whichever is smaller (L/(8r) < L/4 when r > 1/2, larger when r < 1/2). */
static void test_generate_ranges(void)
{
    static const double cases[][2] = {{100, 10}, {100, 0.1}, {1000, 0.5}, {7, 3.5}};
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        const double L = cases[c][0], r = cases[c][1];
        const double a = L / (8 * r), b = L / 4, lo = a < b ? a : b, hi = a < b ? b : a;
        sim_world w;
        const sim_header h = header(5000, L, r, 0);
        CHECK_INT(sim_world_alloc(&w, &h), 0);
        unsigned char *listed = calloc(5001, 1);
        CHECK(listed != NULL);
        sim_generate(&w, &h, listed, 7 + c);
        int bad_pos = 0, bad_speed = 0;
        for (int32_t i = 0; i < w.n; i++) {
            bad_pos += !(w.x[i] >= r && w.x[i] <= L - r && w.y[i] >= r && w.y[i] <= L - r);
            const double s = hypot(w.vx[i], w.vy[i]);
            bad_speed += !(s >= lo * (1 - 1e-14) && s <= hi * (1 + 1e-14));
        }
        CHECK_INT(bad_pos, 0);
        CHECK_INT(bad_speed, 0);
        free(listed);
        sim_world_free(&w);
    }
}

/* Generation in chunks side by side draws what one stream in index order draws: a world of a
 * few chunks with listed particles between them, on three threads, against the stream replayed
 * here one particle after the other. */
static void test_generate_chunks_are_one_stream(void)
{
    const int32_t n = 3 * 4096 + 17;
    sim_world w;
    const sim_header h = header(n, 1000, 1, 0);
    CHECK_INT(sim_world_alloc(&w, &h), 0);
    unsigned char *listed = calloc((size_t)n + 1, 1);
    CHECK(listed != NULL);
    if (!listed)
        return;
    for (int32_t i = 5; i < n; i += 997)
        listed[i] = 1, put(&w, i, 500, 500, 0, 0);
    omp_set_num_threads(3);
    sim_generate(&w, &h, listed, 42);
    omp_set_num_threads(1);
    uint64_t state = 42;
    int differing = 0;
    const double lo = 1000.0 / 8, hi = 1000.0 / 4;
    for (int32_t i = 0; i < n; i++) {
        if (listed[i]) {
            differing += w.x[i] != 500;
            continue;
        }
        const double u1 = sim_uniform(&state), u2 = sim_uniform(&state);
        const double u3 = sim_uniform(&state), u4 = sim_uniform(&state);
        const double speed = lo + u3 * (hi - lo), angle = 6.283185307179586476925286766559 * u4;
        differing += w.x[i] != (sim_real)(1 + u1 * 998) || w.y[i] != (sim_real)(1 + u2 * 998) ||
                     w.vx[i] != (sim_real)(speed * cos(angle)) ||
                     w.vy[i] != (sim_real)(speed * sin(angle));
    }
    CHECK_INT(differing, 0);
    free(listed);
    sim_world_free(&w);
}

/* ---- input (SPEC §1) ---- */

static void test_parse_header_ok(void)
{
    static const char text[] = "  3\t100.5 0.25\r\n  7 \n print\n";
    sim_lexer lx;
    sim_header h;
    sim_error err = {0};
    sim_lexer_init(&lx, text, sizeof text - 1);
    CHECK_INT(sim_parse_header(&lx, &h, &err), 0);
    CHECK_INT(h.n, 3);
    CHECK_REAL(h.L, 100.5);
    CHECK_REAL(h.r, 0.25);
    CHECK_INT(h.steps, 7);
    CHECK_INT(h.mode, SIM_MODE_PRINT);

    static const char text2[] = "0 10 5 0\nperf";
    sim_lexer_init(&lx, text2, sizeof text2 - 1);
    CHECK_INT(sim_parse_header(&lx, &h, &err), 0);
    CHECK_INT(h.n, 0);
    CHECK_REAL(h.r, 5); /* 2r == L is allowed */
    CHECK_INT(h.steps, 0);
    CHECK_INT(h.mode, SIM_MODE_PERF);
}

typedef struct bad_case {
    const char *text;
    long line;        /* the line SPEC's message must name */
    const char *what; /* a part of the message naming the token or rule */
} bad_case;

static void test_parse_header_errors(void)
{
    static const bad_case cases[] = {
        {"", 1, "N"},
        {"\n\n", 2, "N"},
        {"abc 100 1 1\nperf\n", 1, "N"},
        {"-1 100 1 1\nperf\n", 1, "N"},
        {"2.5 100 1 1\nperf\n", 1, "N"},
        {"2147483648 100 1 1\nperf\n", 1, "N"},
        {"2 nan 1 1\nperf\n", 1, "L"},
        {"2 100 inf 1\nperf\n", 1, "r"},
        {"2 100 -inf 1\nperf\n", 1, "r"},
        {"2 1e999 1 1\nperf\n", 1, "L"},
        {"2 100x 1 1\nperf\n", 1, "L"},
        {"2 100 0 1\nperf\n", 1, "r"},
        {"2 100 -1 1\nperf\n", 1, "r"},
        {"2 100 50.5 1\nperf\n", 1, "2r"},
        {"2 100 1 -1\nperf\n", 1, "S"},
        {"2 100 1 1.5\nperf\n", 1, "S"},
        {"2 100 1 99999999999999999999\nperf\n", 1, "S"},
        {"2 100 1\n", 1, "S"},
        {"2\n100\n1\n\n", 4, "S"}, /* a final newline ends line 4 */
        {"2 100 1 1\n", 1, "MODE"},
        {"2 100 1 1\nfast\n", 2, "MODE"},
        {"2 100 1 1\n\n\nPERF\n", 4, "MODE"},
    };
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        sim_lexer lx;
        sim_header h;
        sim_error err = {.line = -7};
        sim_lexer_init(&lx, cases[k].text, strlen(cases[k].text));
        const int before = checks_failed;
        CHECK_INT(sim_parse_header(&lx, &h, &err), -1);
        CHECK_INT(err.line, cases[k].line);
        CHECK_CONTAINS(err.what, cases[k].what);
        if (checks_failed != before)
            printf("  (header case %zu: \"%s\")\n", k, cases[k].text);
    }
}

/* Parse a whole input into a fresh world. Returns the parser's status; *w is freed. */
static int parse_all(const char *text, sim_error *err, double out[][4], unsigned char *listed_out,
                     int32_t max_n)
{
    sim_lexer lx;
    sim_header h;
    sim_lexer_init(&lx, text, strlen(text));
    if (sim_parse_header(&lx, &h, err))
        return -2;
    if (h.n > max_n)
        return -3;
    sim_world w;
    if (sim_world_alloc(&w, &h))
        return -4;
    unsigned char *listed = calloc((size_t)h.n + 1, 1);
    const int rc = listed ? sim_parse_particles(&lx, &h, &w, listed, err) : -4;
    for (int32_t i = 0; rc == 0 && i < h.n; i++) {
        if (out) {
            out[i][0] = w.x[i];
            out[i][1] = w.y[i];
            out[i][2] = w.vx[i];
            out[i][3] = w.vy[i];
        }
        if (listed_out)
            listed_out[i] = listed[i];
    }
    free(listed);
    sim_world_free(&w);
    return rc;
}

static void test_parse_particles_ok(void)
{
    static const char text[] = "4 20 1 3\nperf\n2 1 19 -0.5 1e-3\n0   10.25 5 0 0\n\n";
    double p[4][4];
    unsigned char listed[4];
    sim_error err;
    CHECK_INT(parse_all(text, &err, p, listed, 4), 0);
    CHECK_INT(listed[0], 1);
    CHECK_INT(listed[1], 0);
    CHECK_INT(listed[2], 1);
    CHECK_INT(listed[3], 0);
    CHECK_REAL(p[2][0], 1); /* x = r and y = L - r are inside */
    CHECK_REAL(p[2][1], 19);
    CHECK_REAL(p[2][2], -0.5);
    CHECK_REAL(p[2][3], 1e-3);
    CHECK_REAL(p[0][0], 10.25);
    CHECK_REAL(p[0][1], 5);

    /* All N listed, tokens spread over lines: whitespace-separated tokens. */
    CHECK_INT(parse_all("2 10 1 1 perf 0 5 5 1 1\n1\n6\n6\n0\n0", &err, p, listed, 2), 0);
    CHECK_REAL(p[1][0], 6);
    /* N = 0 with nothing after the mode. */
    CHECK_INT(parse_all("0 10 1 1\nprint\n", &err, NULL, NULL, 0), 0);
}

static void test_parse_particles_errors(void)
{
    static const bad_case cases[] = {
        {"2 100 1 1\nperf\n0 10 10 1\n", 3, "vy"},               /* truncated last line */
        {"2 100 1 1\nperf\n0 10 10 1 1 x\n", 3, "'x'"},          /* trailing garbage */
        {"2 100 1 1\nperf\n0 10 10 1 1\n1 10 10 1 1 7\n", 4, "'7'"}, /* more lines than N */
        {"1 100 1 1\nperf\n0 10 10 1 1\n0 10 10 1 1\n", 4, "0"},
        {"2 100 1 1\nperf\n0 10 10 1 1\n0 20 20 1 1\n", 4, "duplicate"},
        {"2 100 1 1\nperf\n2 10 10 1 1\n", 3, "2"},
        {"2 100 1 1\nperf\n-1 10 10 1 1\n", 3, "-1"},
        {"2 100 1 1\nperf\n1.0 10 10 1 1\n", 3, "1.0"},
        {"0 100 1 1\nperf\n0 10 10 1 1\n", 3, "0"},
        {"2 100 1 1\nperf\n0 0.5 10 1 1\n", 3, "x=0.5"},
        {"2 100 1 1\nperf\n0 99.5 10 1 1\n", 3, "x=99.5"},
        {"2 100 1 1\nperf\n0 10 -3 1 1\n", 3, "y=-3"},
        {"2 100 1 1\nperf\n0 10 99.000001 1 1\n", 3, "y"},
        {"2 100 1 1\nperf\n0 10 10 nan 1\n", 3, "vx"},
        {"2 100 1 1\nperf\n0 10 10 1 -inf\n", 3, "vy"},
        {"2 100 1 1\nperf\n0 10 10 1e400 1\n", 3, "vx"},
        {"2 100 1 1\nperf\n0 10 10 1 1\n\n\n1 10 10 1 NaN\n", 6, "vy"},
        {"2 100 1 1\nperf\n0 nan 10 1 1\n", 3, "x"},
        {"3 100 1 1\nperf\n0 10 10 1 1\n1 20 20 1 1\n2 30 30 1\n", 5, "vy"},
        {"3 100 1 1\nperf\n0 10 10 1\n1 20 20 1 1\n", 4, "20"}, /* vy taken from line 4 */
    };
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        sim_error err = {.line = -7};
        const int before = checks_failed;
        CHECK_INT(parse_all(cases[k].text, &err, NULL, NULL, 3), -1);
        CHECK_INT(err.line, cases[k].line);
        CHECK_CONTAINS(err.what, cases[k].what);
        if (checks_failed != before)
            printf("  (particle case %zu: \"%s\")\n", k, cases[k].text);
    }
}

/* ---- wall time (SPEC §2) ---- */

static void test_wall_time(void)
{
    sim_world w;
    world_init(&w, 8, 100, 1);
    put(&w, 0, 50, 50, 0, 0);          /* at rest: never */
    put(&w, 1, 50, 50, 1, 0);          /* (99 - 50) / 1 */
    put(&w, 2, 50, 50, 0, -2);         /* (1 - 50) / -2 */
    put(&w, 3, 1, 50, -1, 0);          /* at the wall, moving in: (1 - 1) / -1 = -0 */
    put(&w, 4, 98.5, 98.5, 1, 1);      /* corner, both 0.5 */
    put(&w, 5, 98, 2, 2, -4);          /* min(0.5, 0.25) */
    put(&w, 6, 1, 99, -0.0, 0.5);      /* -0 velocity never hits; y: 0 / 0.5 = 0 */
    put(&w, 7, 99, 50, -0.5, 0);       /* at the wall, moving out: (1 - 99) / -0.5 */
    CHECK(isinf(sim_wall_time(&w, 0)) && sim_wall_time(&w, 0) > 0);
    CHECK_REAL(sim_wall_time(&w, 1), 49);
    CHECK_REAL(sim_wall_time(&w, 2), 24.5);
    CHECK(sim_wall_time(&w, 3) == 0);
    CHECK_REAL(sim_wall_time(&w, 4), 0.5);
    CHECK_REAL(sim_wall_time(&w, 5), 0.25);
    CHECK_REAL(sim_wall_time(&w, 6), 0);
    CHECK_REAL(sim_wall_time(&w, 7), 196);
    sim_world_free(&w);
}

/* ---- pair time (SPEC §2) ---- */

typedef struct pair_case {
    double p[2][4]; /* x y vx vy of i and j */
    int hit;
    double t;
    const char *name;
} pair_case;

static void test_pair_time_cases(void)
{
    /* L = 100, r = 1: (2r)^2 = 4. Each t derived in the comment. */
    static const pair_case cases[] = {
        /* dx 3, Dx -2: b -6, c 5, a 4, disc 16, t = 5/10 */
        {{{10, 50, 1, 0}, {13, 50, -1, 0}}, 1, 0.5, "head-on"},
        /* dx 4: b -8, c 12, t = 12/12 = 1, included */
        {{{10, 50, 1, 0}, {14, 50, -1, 0}}, 1, 1, "contact at t = 1"},
        /* dx 4.5: c 16.25, b -9, t = 16.25/13 = 1.25 > 1 */
        {{{10, 50, 1, 0}, {14.5, 50, -1, 0}}, 0, 0, "contact after the step"},
        /* touching, approaching: c 0, b -4: t = 0 */
        {{{10, 50, 1, 0}, {12, 50, -1, 0}}, 1, 0, "touching, approaching"},
        /* touching, receding: b 4 */
        {{{10, 50, -1, 0}, {12, 50, 1, 0}}, 0, 0, "touching, receding"},
        /* touching, at rest relative: b 0 */
        {{{10, 50, 1, 1}, {12, 50, 1, 1}}, 0, 0, "touching, same velocity"},
        /* overlapping and approaching: c -3 < 0 */
        {{{10, 50, 1, 0}, {11, 50, -1, 0}}, 0, 0, "overlapping"},
        /* same centre: b 0 */
        {{{10, 50, 1, 0}, {10, 50, -1, 0}}, 0, 0, "same centre"},
        /* parallel tracks 3 apart: b = 0 */
        {{{10, 50, 1, 0}, {10, 53, 1, 0}}, 0, 0, "side by side"},
        /* miss: dx 4, dy 3, Dx -2: b -8, cross = 4*0 - 3*(-2) = 6, disc 16 - 36 < 0 */
        {{{10, 50, 1, 0}, {14, 53, -1, 0}}, 0, 0, "miss"},
        /* grazing: dx 1, dy 2, Dx -1: b -1, c 1, a 1, cross 2, disc 0: t = 1/1 */
        {{{10, 50, 0, 0}, {11, 52, -1, 0}}, 1, 1, "grazing, disc = 0"},
        /* diagonal: dx = dy = 3, Dx = Dy = -2: b -12, c 14, a 8, cross 0, disc 32;
         * t = 14 / (12 + sqrt(32)) */
        {{{10, 10, 1, 1}, {13, 13, -1, -1}}, 1, 14 / (12 + 0x1.6a09e667f3bcdp+2), "diagonal"},
        /* j behind i catching up: dx -3.5, Dx 2: b -7, c 8.25, a 4, disc 16, t = 0.75 */
        {{{98.5, 50, 1, 0}, {95, 50, 3, 0}}, 1, 0.75, "catching up"},
        /* far apart, fast: dx 1025, Dx -1024 (r = 1 -> c = 1050621), a 1024^2, disc 4*1024^2:
         * t = 1050621 / (1049600 + 2048) = 1050621/1051648 */
        {{{1, 50, 512, 0}, {1026, 50, -512, 0}}, 1, 1050621.0 / 1051648.0, "far and fast"},
    };
    sim_world w;
    world_init(&w, 2, 2000, 1);
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        const pair_case *c = &cases[k];
        put(&w, 0, c->p[0][0], c->p[0][1], c->p[0][2], c->p[0][3]);
        put(&w, 1, c->p[1][0], c->p[1][1], c->p[1][2], c->p[1][3]);
        sim_real t = -12345;
        const int before = checks_failed;
        const bool hit = sim_pair_time(&w, 0, 1, &t);
        CHECK_INT(hit, c->hit);
        if (c->hit)
            CHECK_REAL(t, c->t);
        if (checks_failed != before)
            printf("  (pair case %zu: %s)\n", k, c->name);
    }
    sim_world_free(&w);
}

/* SPEC §2's expressions, evaluated literally here, in the same order (this file is compiled
 * with -ffp-contract=off like the core). */
static bool spec_pair_time(const sim_world *w, int32_t i, int32_t j, double *t)
{
    const double dx = w->x[j] - w->x[i], dy = w->y[j] - w->y[i];
    const double Dx = w->vx[j] - w->vx[i], Dy = w->vy[j] - w->vy[i];
    const double b = dx * Dx + dy * Dy;
    if (b >= 0)
        return false;
    const double two_r = 2 * w->r;
    const double c = (dx * dx + dy * dy) - two_r * two_r;
    if (c < 0)
        return false;
    const double a = Dx * Dx + Dy * Dy;
    const double cross = dx * Dy - dy * Dx;
    const double disc = two_r * two_r * a - cross * cross;
    if (disc < 0)
        return false;
    const double root = c / (-b + sqrt(disc));
    if (!(root <= 1))
        return false;
    *t = root;
    return true;
}

/* A random pair, often near contact, sometimes far apart with a small radius. */
static void random_pair(sim_world *w, int32_t i, int32_t j)
{
    const double L = w->L, r = w->r;
    const double x = r + rnd() * (L - 2 * r), y = r + rnd() * (L - 2 * r);
    const double dist = rnd() < 0.5 ? 2 * r * (0.9 + 0.4 * rnd()) : rnd() * L / 2;
    const double ang = 6.283185307179586 * rnd();
    double xj = x + dist * cos(ang), yj = y + dist * sin(ang);
    xj = xj < r ? r : xj > L - r ? L - r : xj;
    yj = yj < r ? r : yj > L - r ? L - r : yj;
    const double s = rnd() < 0.5 ? 3 * r : L / 4;
    put(w, i, x, y, s * (2 * rnd() - 1), s * (2 * rnd() - 1));
    put(w, j, xj, yj, s * (2 * rnd() - 1), s * (2 * rnd() - 1));
}

static void test_pair_time_is_spec_formula(void)
{
    static const double radii[][2] = {{100, 1}, {1000, 0.01}, {1e6, 1e-3}, {10, 2.5}};
    int mismatches = 0, hits = 0;
    for (size_t c = 0; c < sizeof radii / sizeof radii[0]; c++) {
        sim_world w;
        world_init(&w, 2, radii[c][0], radii[c][1]);
        for (int k = 0; k < 50000; k++) {
            random_pair(&w, 0, 1);
            double want = -1;
            sim_real got = -1;
            const bool hw = spec_pair_time(&w, 0, 1, &want), hg = sim_pair_time(&w, 0, 1, &got);
            hits += hw;
            if (hw != hg || (hw && !(got == want))) {
                if (mismatches++ < 5)
                    fail_at(__FILE__, __LINE__, "pair (%a,%a,%a,%a)-(%a,%a,%a,%a) r=%g: got %d %.17g,"
                            " expected %d %.17g", w.x[0], w.y[0], w.vx[0], w.vy[0], w.x[1], w.y[1],
                            w.vx[1], w.vy[1], (double)w.r, hg, (double)got, hw, want);
            }
        }
        sim_world_free(&w);
    }
    CHECK_INT(mismatches, 0);
    CHECK(hits > 1000); /* the sample did exercise the candidate branch */
}

/* ---- the vectorised row scan against the scalar pair test ---- */

static int cand_order(const void *pa, const void *pb)
{
    const sim_cand *a = pa, *b = pb;
    if (a->i != b->i)
        return a->i < b->i ? -1 : 1;
    return (a->j > b->j) - (a->j < b->j);
}

/* Particles whose state or counts differ between two worlds of the same size, bit for bit. */
static int32_t particles_differing(const sim_world *a, const sim_world *b)
{
    int32_t differ = 0;
    for (int32_t i = 0; i < a->n; i++)
        differ += memcmp(&a->x[i], &b->x[i], sizeof a->x[i]) ||
                  memcmp(&a->y[i], &b->y[i], sizeof a->y[i]) ||
                  memcmp(&a->vx[i], &b->vx[i], sizeof a->vx[i]) ||
                  memcmp(&a->vy[i], &b->vy[i], sizeof a->vy[i]) || a->pcoll[i] != b->pcoll[i] ||
                  a->wcoll[i] != b->wcoll[i];
    return differ;
}

/* A dense, slow world: many near contacts, touching and grazing pairs, overlaps. */
static void dense_world(sim_world *w, int32_t n, double L)
{
    world_init(w, n, L, 1);
    for (int32_t i = 0; i < n; i++) {
        const double x = 1 + rnd() * (L - 2), y = 1 + rnd() * (L - 2);
        put(w, i, x, y, 2 * rnd() - 1, 2 * rnd() - 1);
    }
    /* A few exact cases inside the blocks: touching approaching, grazing, at rest. */
    if (n <= 200 || L < 40)
        return;
    put(w, 5, 10, 10, 1, 0);
    put(w, 70, 12, 10, -1, 0);
    put(w, 6, 20, 20, 0, 0);
    put(w, 140, 21, 22, -1, 0);
    put(w, 7, 30, 30, 0, 0);
    put(w, 200, 32, 30, 0, 0);
}

static void test_scan_row_matches_pair_time(void)
{
    sim_world w;
    dense_world(&w, 700, 60);
    sim_cand_buf buf = {0};
    int missing = 0, extra = 0, total = 0;
    uint64_t tests = 0;
    for (int32_t i = 0; i < w.n; i++) {
        /* Whole rows, and an arbitrary sub-range of the row. */
        for (int part = 0; part < 2; part++) {
            int32_t jb = i + 1, je = w.n;
            if (part == 1) {
                jb = i + 1 + (int32_t)(rnd() * (w.n - i));
                je = jb + (int32_t)(rnd() * (w.n - jb + 1));
                if (je > w.n)
                    je = w.n;
            }
            buf.len = 0;
            buf.pair_tests = 0;
            sim_scan_row(&w, i, jb, je, &buf);
            tests += buf.pair_tests;
            CHECK_U64(buf.pair_tests, (uint64_t)(je > jb ? je - jb : 0));
            qsort(buf.items, buf.len, sizeof *buf.items, cand_order);
            size_t k = 0;
            for (int32_t j = jb; j < je; j++) {
                sim_real t;
                const bool hit = sim_pair_time(&w, i, j, &t);
                const bool found = k < buf.len && buf.items[k].j == j;
                if (hit && !found && missing++ < 5)
                    fail_at(__FILE__, __LINE__, "scan missed pair (%d, %d) t=%.17g", i, j,
                            (double)t);
                if (found && !hit && extra++ < 5)
                    fail_at(__FILE__, __LINE__, "scan added pair (%d, %d)", i, j);
                if (found && hit && !(buf.items[k].t == t))
                    fail_at(__FILE__, __LINE__, "scan pair (%d, %d): t %.17g vs %.17g", i, j,
                            (double)buf.items[k].t, (double)t);
                if (found) {
                    CHECK_INT(buf.items[k].i, i);
                    k++;
                }
                total += hit && part == 0;
            }
            CHECK_U64(k, buf.len);
        }
    }
    CHECK(!buf.failed);
    CHECK_INT(missing, 0);
    CHECK_INT(extra, 0);
    CHECK(total > 200);
    free(buf.items);
    sim_world_free(&w);
}

/* The vector pass must keep a pair whose disc is exactly 0 (grazing) even when nothing else in
 * its block passes: one mover among discs at rest, all off its path (|cross| > 2r, disc < 0). */
static void test_scan_row_grazing_alone(void)
{
    sim_world w;
    world_init(&w, 300, 100, 1);
    for (int32_t j = 0; j < w.n; j++) /* at rest, on a grid in y >= 60 */
        put(&w, j, 2 + (j % 40) * 2.4, 60 + (j / 40) * 4, 0, 0);
    /* 3 moves along y = 50 at vx 1; 150 at rest at (11, 52): dx 1, dy 2, Dx -1, Dy 0:
     * b -1, c 1, a 1, cross 2, disc 4 - 4 = 0: a candidate at t = 1 / (1 + 0) = 1. */
    put(&w, 3, 10, 50, 1, 0);
    put(&w, 150, 11, 52, 0, 0);
    /* The same with the mover as j: 8 at rest at (59, 28), 290 at (60, 30) moving at vx -1. */
    put(&w, 8, 59, 28, 0, 0);
    put(&w, 290, 60, 30, -1, 0);
    sim_cand_buf buf = {0};
    sim_scan_row(&w, 3, 4, w.n, &buf);
    CHECK_U64(buf.len, 1);
    if (buf.len == 1) {
        CHECK_INT(buf.items[0].j, 150);
        CHECK_REAL(buf.items[0].t, 1);
    }
    buf.len = 0;
    sim_scan_row(&w, 8, 9, w.n, &buf);
    CHECK_U64(buf.len, 1);
    if (buf.len == 1) {
        CHECK_INT(buf.items[0].j, 290);
        CHECK_REAL(buf.items[0].t, 1);
    }
    free(buf.items);
    sim_world_free(&w);
}

static void test_row_tiles(void)
{
    sim_world w;
    world_init(&w, 0, 100, 1);
    CHECK_INT(sim_row_tiles(&w, 0), 0);
    sim_world_free(&w);

    const int32_t n = 2 * SIM_TILE + 3;
    dense_world(&w, n, 60);
    CHECK_INT(sim_row_tiles(&w, 0), 3);             /* n - 1 = 2*TILE + 2 pairs */
    CHECK_INT(sim_row_tiles(&w, 2), 2);             /* exactly 2*TILE */
    CHECK_INT(sim_row_tiles(&w, n - 2), 1);
    CHECK_INT(sim_row_tiles(&w, n - 1), 0);
    /* The tiles of a row cover it exactly once: same pair count and candidates as the row. */
    sim_cand_buf row = {0}, tiles = {0};
    for (int32_t i = 0; i < n; i++) {
        row.len = tiles.len = 0;
        row.pair_tests = tiles.pair_tests = 0;
        sim_scan_row(&w, i, i + 1, n, &row);
        for (int32_t k = 0; k < sim_row_tiles(&w, i); k++)
            sim_scan_tile(&w, i, k, &tiles);
        CHECK_U64(tiles.pair_tests, (uint64_t)(n - 1 - i));
        CHECK_U64(tiles.len, row.len);
        CHECK(row.len == tiles.len &&
              memcmp(row.items, tiles.items, row.len * sizeof *row.items) == 0);
    }
    free(row.items);
    free(tiles.items);
    sim_world_free(&w);
}

static void test_cand_push_grows(void)
{
    sim_cand_buf buf = {0};
    for (int32_t k = 0; k < 5000; k++)
        sim_cand_push(&buf, (sim_real)k / 8, k, k + 1);
    CHECK(!buf.failed);
    CHECK_U64(buf.len, 5000);
    CHECK(buf.cap >= buf.len);
    int wrong = 0;
    for (int32_t k = 0; k < 5000; k++)
        wrong += !(buf.items[k].t == (sim_real)k / 8 && buf.items[k].i == k &&
                   buf.items[k].j == k + 1);
    CHECK_INT(wrong, 0);
    free(buf.items);
}

/* ---- world memory ---- */

static void test_world_alloc(void)
{
    sim_world w;
    const sim_header h0 = header(0, 10, 0.5, 1);
    CHECK_INT(sim_world_alloc(&w, &h0), 0);
    CHECK_INT(w.n, 0);
    CHECK(w.x && w.y && w.vx && w.vy && w.pcoll && w.wcoll);
    CHECK(w.x != w.y && w.vx != w.vy);
    CHECK_REAL(w.lo, 0.5);
    CHECK_REAL(w.hi, 9.5);
    CHECK_REAL(w.diam2, 1);
    sim_world_free(&w);
    CHECK(w.x == NULL && w.pcoll == NULL);

    const sim_header h = header(1000, 100, 1.5, 1);
    CHECK_INT(sim_world_alloc(&w, &h), 0);
    CHECK_REAL(w.diam2, 9);
    int64_t counts = 0;
    for (int32_t i = 0; i < w.n; i++)
        counts += w.pcoll[i] + w.wcoll[i];
    CHECK_INT(counts, 0);
    sim_world_free(&w);
    CHECK(sim_bytes_per_particle() >= 4 * sizeof(sim_real) + 2 * sizeof(int64_t));
}

/* ---- candidate order (SPEC §2) ---- */

/* The SPEC key, written here independently of the core. */
static int spec_key_cmp(const void *pa, const void *pb)
{
    const sim_cand *a = pa, *b = pb;
    if (a->t != b->t)
        return a->t < b->t ? -1 : 1;
    if ((a->j == SIM_WALL) != (b->j == SIM_WALL))
        return a->j == SIM_WALL ? 1 : -1;
    if (a->i != b->i)
        return a->i < b->i ? -1 : 1;
    return a->j < b->j ? -1 : a->j > b->j;
}

/* The radix sort gives the order of the full key, on lists full of ties (few distinct times,
 * -0.0 beside 0.0, negative times from rounding, walls and pairs of the same particle). */
static void test_sort_candidates_matches_the_spec_key(void)
{
    enum { LEN = 3000 };
    static sim_cand got[LEN], want[LEN], tmp[LEN];
    static const sim_real times[] = {0.0, -0.0, 1.0, 0.5, 0.25, -1e-17, 1e-300, 0.75,
                                     2.0, 0x1.fffffffffffffp-1, 1e-4, 1.5e-4};
    enum { TIMES = sizeof times / sizeof *times };
    for (int round = 0; round < 60; round++) {
        const size_t n = round < 4 ? (size_t)round : (size_t)(rnd() * LEN);
        for (size_t k = 0; k < n; k++) {
            const sim_real t = round % 2 ? times[(int)(rnd() * TIMES)] : (sim_real)rnd();
            const int32_t i = (int32_t)(rnd() * 50);
            const int32_t j = rnd() < 0.3 ? SIM_WALL : i + 1 + (int32_t)(rnd() * 50);
            got[k] = want[k] = (sim_cand){t, i, j};
        }
        /* As the stepper lists a step: pairs first, then walls in increasing i, many at t = 0
         * (particles a wall stopped) beside a few very early pairs. */
        if (round % 3 == 2)
            for (size_t k = n / 2; k < n; k++)
                got[k] = want[k] = (sim_cand){rnd() < 0.3 ? (sim_real)rnd() : 0, (int32_t)k,
                                              SIM_WALL};
        qsort(want, n, sizeof *want, spec_key_cmp);
        CHECK_INT(sim_sort_candidates(got, tmp, n), 0);
        size_t same = 0;
        for (size_t k = 0; k < n; k++)
            same += got[k].t == want[k].t && got[k].i == want[k].i && got[k].j == want[k].j;
        CHECK_INT(same, n);
    }
}

/* ---- output (SPEC §3) ---- */

static void test_format_real(void)
{
    char buf[64];
    static const struct {
        double v;
        const char *fixed, *precise;
    } cases[] = {
        {0.1, "0.10000000", "0.10000000000000001"},
        {-2.5, "-2.50000000", "-2.5"},
        {99, "99.00000000", "99"},
        {1e-9, "0.00000000", "1.0000000000000001e-09"},
        {123456.123456789, "123456.12345679", "123456.12345678901"},
        {0x1.fffffffffffffp-1, "1.00000000", "0.99999999999999989"},
    };
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        sim_format_real(buf, sizeof buf, cases[k].v, false);
        CHECK_STR(buf, cases[k].fixed);
        sim_format_real(buf, sizeof buf, cases[k].v, true);
        CHECK_STR(buf, cases[k].precise);
        /* %.17g round-trips a double exactly. */
        CHECK_REAL(strtod(buf, NULL), cases[k].v);
    }
}

/* sim_fixed8 against the C library's %.8f: one value; returns whether they agree. */
static bool fixed8_agrees(double v)
{
    char got[80], want[80];
    const size_t k = sim_fixed8(got, v);
    snprintf(want, sizeof want, "%.8f", v);
    if (k == 0) /* outside the fast path: only where it says so */
        return !(fabs(v) < 1e10);
    got[k] = '\0';
    if (strcmp(got, want) != 0) {
        CHECK_STR(got, want);
        return false;
    }
    return true;
}

/* Random bit patterns, random magnitudes, every kind of exact tie (v * 10^8 = n + 1/2 exactly
 * when v = odd / 512) and its neighbours, carries into a new digit, zeros and subnormals. */
static void test_fixed8_matches_printf(void)
{
    static const double special[] = {0.0, -0.0, 0x1p-1074, -0x1p-1074, 0x1p-1022, 1e-300,
                                     -1e-9, 5e-9, 4.9999999999999999e-9, 0.999999995,
                                     9.999999995, 0.1, 1.0, 20000.0, 9999999999.9999981};
    bool ok = true;
    for (size_t k = 0; k < sizeof special / sizeof special[0] && ok; k++)
        ok = fixed8_agrees(special[k]) && fixed8_agrees(nextafter(special[k], 1e300)) &&
             fixed8_agrees(nextafter(special[k], -1e300));
    for (int k = 0; k < 300000 && ok; k++) {
        uint64_t bits = rng_state * 0x9E3779B97F4A7C15ULL;
        rnd();
        double v;
        memcpy(&v, &bits, sizeof v);
        const double sign = rnd() < 0.5 ? -1 : 1;
        const double scaled = sign * rnd() * pow(10, (int)(rnd() * 24) - 13);
        const double tie = sign * (2 * floor(rnd() * 1e9) + 1) / 512;
        ok = fixed8_agrees(v) && fixed8_agrees(scaled) && fixed8_agrees(tie) &&
             fixed8_agrees(nextafter(tie, 0)) && fixed8_agrees(nextafter(tie, 2 * tie)) &&
             fixed8_agrees(sign * rnd() * 20000);
    }
    CHECK(ok);
    char buf[80];
    CHECK_INT(sim_fixed8(buf, 1e10), 0);
    CHECK_INT(sim_fixed8(buf, NAN), 0);
    CHECK_INT(sim_fixed8(buf, -INFINITY), 0);
}

static void test_write_blocks(void)
{
    sim_world w;
    world_init(&w, 2, 100, 1);
    put(&w, 0, 10, 50.25, -1, 0.1);
    put(&w, 1, 1, 99, 0, -3);
    w.pcoll[0] = 3;
    w.wcoll[1] = 12;
    char *text = NULL;
    size_t len = 0;
    FILE *f = open_memstream(&text, &len);
    CHECK(f != NULL);
    if (!f)
        return;
    CHECK_INT(sim_write_state(f, &w, 4, false), 0);
    CHECK_INT(sim_write_final(f, &w, 5, false), 0);
    CHECK_INT(sim_write_final(f, &w, 5, true), 0);
    fclose(f);
    CHECK_STR(text, "4 0 10.00000000 50.25000000 -1.00000000 0.10000000\n"
                    "4 1 1.00000000 99.00000000 0.00000000 -3.00000000\n"
                    "5 0 10.00000000 50.25000000 -1.00000000 0.10000000 3 0\n"
                    "5 1 1.00000000 99.00000000 0.00000000 -3.00000000 0 12\n"
                    "5 0 10 50.25 -1 0.10000000000000001 3 0\n"
                    "5 1 1 99 0 -3 0 12\n");
    free(text);

    /* The largest finite values are printed whole, as the C library prints them. */
    put(&w, 0, 10, 50.25, 1e60, -DBL_MAX);
    put(&w, 1, 1, 99, DBL_MAX, -2.5e200);
    text = NULL;
    f = open_memstream(&text, &len);
    CHECK_INT(sim_write_final(f, &w, 5, false), 0);
    fclose(f);
    static char want[4 * SIM_REAL_TEXT_MAX];
    snprintf(want, sizeof want, "5 0 10.00000000 50.25000000 %.8f %.8f 3 0\n"
                                "5 1 1.00000000 99.00000000 %.8f %.8f 0 12\n",
             1e60, -DBL_MAX, DBL_MAX, -2.5e200);
    CHECK_STR(text, want);
    free(text);
    char real[SIM_REAL_TEXT_MAX];
    sim_format_real(real, sizeof real, -DBL_MAX, false);
    CHECK_INT(strlen(real), SIM_REAL_TEXT_MAX - 1);
    CHECK_INT(real[SIM_REAL_TEXT_MAX - 10], '.');

    /* N = 0: nothing at all. */
    sim_world_free(&w);
    world_init(&w, 0, 100, 1);
    text = NULL;
    f = open_memstream(&text, &len);
    CHECK_INT(sim_write_final(f, &w, 3, false), 0);
    fclose(f);
    CHECK_INT(len, 0);
    free(text);
    sim_world_free(&w);
}

/* A block of many particles is formatted by the team chunk by chunk and written in order: the
 * same bytes as one thread's, in both formats. */
static void test_write_blocks_on_a_team(void)
{
    sim_world w;
    dense_world(&w, 40000, 4000);
    for (int32_t i = 0; i < w.n; i++)
        w.pcoll[i] = i % 7, w.wcoll[i] = i % 3;
    char *text[2] = {NULL, NULL};
    size_t len[2] = {0, 0};
    for (int k = 0; k < 2; k++) {
        omp_set_num_threads(k ? 3 : 1);
        FILE *f = open_memstream(&text[k], &len[k]);
        CHECK(f != NULL);
        if (!f)
            return;
        CHECK_INT(sim_write_state(f, &w, 7, false), 0);
        CHECK_INT(sim_write_final(f, &w, 8, true), 0);
        fclose(f);
    }
    omp_set_num_threads(1);
    CHECK(len[0] > (size_t)w.n * 40);
    CHECK_INT(len[1], len[0]);
    CHECK(len[0] == len[1] && memcmp(text[0], text[1], len[0]) == 0);
    free(text[0]);
    free(text[1]);
    sim_world_free(&w);
}

/* --describe's line: the keys in their fixed order, booleans as JSON literals, a missing repair
 * or runtime count as null, a count's nonzero terms only, and every character JSON needs
 * escaped in the strings. */
static void test_describe_json(void)
{
    const sim_variant plain = {.name = "seq", .summary = "every pair", .exact = true,
                               .all_pairs = true};
    const sim_variant odd = {.name = "x\"y", .summary = "a \"quoted\" \\ tab\t line\n bell\a end",
                             .parallel = true, .repairs = "p1"};
    const sim_sync sync = {.regions = {.per_step = 1, .per_row = 2},
                           .grabs = {.per_pair = 3, .per_tile = 4}, .tile = 64};
    const sim_variant counted = {.name = "c", .summary = "", .parallel = true, .sync = &sync,
                                 .mpi = true};
    char *text = NULL;
    size_t len = 0;
    FILE *f = open_memstream(&text, &len);
    CHECK(f != NULL);
    if (!f)
        return;
    CHECK_INT(sim_describe(f, &plain), 0);
    CHECK_INT(sim_describe(f, &odd), 0);
    CHECK_INT(sim_describe(f, &counted), 0);
    fclose(f);
    CHECK_STR(text, "{\"name\":\"seq\",\"summary\":\"every pair\",\"exact\":true,"
                    "\"parallel\":false,\"all_pairs\":true,\"repairs\":null,\"mpi\":false,"
                    "\"sync\":null}\n"
                    "{\"name\":\"x\\\"y\",\"summary\":\"a \\\"quoted\\\" \\\\ tab\\t line\\n "
                    "bell\\u0007 end\",\"exact\":false,\"parallel\":true,\"all_pairs\":false,"
                    "\"repairs\":\"p1\",\"mpi\":false,\"sync\":null}\n"
                    "{\"name\":\"c\",\"summary\":\"\",\"exact\":false,\"parallel\":true,"
                    "\"all_pairs\":false,\"repairs\":null,\"mpi\":true,\"sync\":{\"regions\":{\"step\":1,"
                    "\"row\":2},\"nested_regions\":{},\"barriers\":{},\"grabs\":{\"pair\":3,"
                    "\"tile\":4},\"tile\":64}}\n");
    free(text);
}

/* ---- one step (SPEC §2) ---- */

/* Head-on at t = 1/2 (tests/c/scenes/head_on.md): velocities swap, both finish the step. */
static void test_step_head_on(void)
{
    sim_world w;
    world_init(&w, 2, 100, 1);
    put(&w, 0, 10, 50, 1, 0);
    put(&w, 1, 13, 50, -1, 0);
    sim_stats st = {0};
    run_steps(&w, &sim_variant_def, 1, &st);
    CHECK_REAL(w.x[0], 10);
    CHECK_REAL(w.vx[0], -1);
    CHECK_REAL(w.x[1], 13);
    CHECK_REAL(w.vx[1], 1);
    CHECK_REAL(w.y[0], 50);
    CHECK_REAL(w.vy[0], 0);
    CHECK_REAL(w.vy[1], 0);
    CHECK_INT(w.pcoll[0], 1);
    CHECK_INT(w.pcoll[1], 1);
    CHECK_INT(w.wcoll[0] + w.wcoll[1], 0);
    CHECK_U64(st.pair_tests, 1);
    CHECK_U64(st.candidates, 1);
    CHECK_U64(st.pair_collisions, 1);
    CHECK_U64(st.wall_collisions, 0);
    sim_world_free(&w);
}

/* tests/c/scenes/pair_wall_tie.md: at equal t the pair wins over both walls; after the
 * collision both stop at the wall (tw' = 0) and bounce at t = 0 of the next step. */
static void test_step_pair_before_wall(void)
{
    sim_world w;
    world_init(&w, 2, 100, 1);
    put(&w, 0, 98, 50, 2, 2);
    put(&w, 1, 98, 54, 2, -2);
    sim_stats st = {0};
    run_steps(&w, &sim_variant_def, 1, &st);
    CHECK_U64(st.candidates, 3);
    CHECK_U64(st.pair_collisions, 1);
    CHECK_U64(st.wall_collisions, 0);
    CHECK_REAL(w.x[0], 99);
    CHECK_REAL(w.y[0], 51);
    CHECK_REAL(w.vx[0], 2);
    CHECK_REAL(w.vy[0], -2);
    CHECK_REAL(w.x[1], 99);
    CHECK_REAL(w.y[1], 53);
    CHECK_REAL(w.vx[1], 2);
    CHECK_REAL(w.vy[1], 2);
    CHECK(sim_wall_time(&w, 0) == 0);
    st = (sim_stats){0};
    run_steps(&w, &sim_variant_def, 1, &st);
    CHECK_U64(st.candidates, 2);
    CHECK_U64(st.wall_collisions, 2);
    CHECK_REAL(w.x[0], 97);
    CHECK_REAL(w.y[0], 49);
    CHECK_REAL(w.vx[0], -2);
    CHECK_REAL(w.x[1], 97);
    CHECK_REAL(w.y[1], 55);
    CHECK_INT(w.pcoll[0] + w.pcoll[1], 2);
    CHECK_INT(w.wcoll[0] + w.wcoll[1], 2);
    sim_world_free(&w);
}

/* A particle moving into the wall it sits on has wall time -0: it bounces at t = 0 (a -0 key
 * sorts equal to 0, and pairs at 0 still go first). tests/c/scenes/wall_start.md, particle 2. */
static void test_step_at_wall_moving_in(void)
{
    sim_world w;
    world_init(&w, 3, 100, 1);
    put(&w, 0, 1, 20, -1, 0);
    /* 1 and 2 touch at the left wall and approach (pair at t = 0); 1 also moves into it. */
    put(&w, 1, 1, 60, -1, 1);
    put(&w, 2, 1, 62, -1, -1);
    sim_stats st = {0};
    run_steps(&w, &sim_variant_def, 1, &st);
    CHECK_REAL(w.x[0], 2);
    CHECK_REAL(w.vx[0], 1);
    CHECK_INT(w.wcoll[0], 1);
    /* Pair (1,2) at t = 0, n = (0, 1): vy swap, vx = -1 kept; finish(1) meets the wall at
     * once (tx' = -0 -> 0 < 1): both stay where they are, x = 1. */
    CHECK_INT(w.pcoll[1], 1);
    CHECK_INT(w.pcoll[2], 1);
    CHECK_INT(w.wcoll[1] + w.wcoll[2], 0);
    CHECK_REAL(w.x[1], 1);
    CHECK_REAL(w.y[1], 60);
    CHECK_REAL(w.vy[1], -1);
    CHECK_REAL(w.vx[1], -1);
    CHECK_REAL(w.x[2], 1);
    CHECK_REAL(w.y[2], 62);
    CHECK_REAL(w.vy[2], 1);
    CHECK_U64(st.wall_collisions, 1);
    CHECK_U64(st.pair_collisions, 1);
    sim_world_free(&w);
}

/* pair_tests counts every pair once per step, candidates counts what was sorted. */
static void test_step_stats(void)
{
    sim_world w;
    dense_world(&w, 50, 30);
    sim_stats st = {0};
    run_steps(&w, &sim_variant_def, 7, &st);
    CHECK_U64(st.pair_tests, 7 * 50 * 49 / 2);
    int64_t pc = 0, wc = 0;
    for (int32_t i = 0; i < w.n; i++) {
        pc += w.pcoll[i];
        wc += w.wcoll[i];
    }
    CHECK_INT(pc % 2, 0);
    CHECK_U64((uint64_t)pc, 2 * st.pair_collisions);
    CHECK_U64((uint64_t)wc, st.wall_collisions);
    CHECK(st.candidates >= st.pair_collisions + st.wall_collisions);
    CHECK(st.pair_collisions > 0);
    sim_world_free(&w);
}

/* N = 0 and S steps: nothing happens, nothing breaks. */
static void test_step_empty_world(void)
{
    sim_world w;
    world_init(&w, 0, 100, 1);
    sim_stats st = {0};
    run_steps(&w, &sim_variant_def, 3, &st);
    CHECK_U64(st.pair_tests, 0);
    CHECK_U64(st.candidates, 0);
    sim_world_free(&w);
}

/* The result must not depend on the order in which candidates are found or on how they are
 * spread over buffers (SPEC §2 Resolution): forwards in one buffer vs backwards in three. */
static void test_step_order_independent(void)
{
    sim_world a, b;
    dense_world(&a, 400, 40);
    world_init(&b, 400, 40, 1);
    memcpy(b.x, a.x, 400 * sizeof *a.x);
    memcpy(b.y, a.y, 400 * sizeof *a.y);
    memcpy(b.vx, a.vx, 400 * sizeof *a.vx);
    memcpy(b.vy, a.vy, 400 * sizeof *a.vy);
    /* Exact ties in t: a 3x3 square of four discs heading for its centre (scenes/tie4.md). */
    put(&a, 100, 25, 25, 1, 1);
    put(&a, 101, 28, 25, -1, 1);
    put(&a, 102, 25, 28, 1, -1);
    put(&a, 103, 28, 28, -1, -1);
    for (int32_t k = 100; k < 104; k++)
        put(&b, k, a.x[k], a.y[k], a.vx[k], a.vy[k]);
    sim_stats sa = {0}, sb = {0};
    run_steps(&a, &sim_variant_def, 6, &sa);
    run_steps(&b, &reversed_variant, 6, &sb);
    CHECK_INT(particles_differing(&a, &b), 0);
    CHECK_U64(sb.pair_tests, sa.pair_tests);
    CHECK_U64(sb.candidates, sa.candidates);
    CHECK_U64(sb.pair_collisions, sa.pair_collisions);
    CHECK_U64(sb.wall_collisions, sa.wall_collisions);
    CHECK(sa.pair_collisions > 50);
    sim_world_free(&a);
    sim_world_free(&b);
}

/* The pairs found backwards over three buffers, stepped by a parallel stepper: above 65536 pair
 * candidates a step the team sorts them (coarse buckets, then fine ones), and the steps must
 * be those of one thread's sort. */
static const sim_variant reversed_parallel_variant = {
    .name = "reversed_parallel",
    .exact = true,
    .parallel = true,
    .buffer_count = three_buffers,
    .find_pairs = find_pairs_reversed,
};

static void test_step_team_sort(void)
{
    sim_world a, b;
    world_init(&a, 8000, 200, 1);
    for (int32_t i = 0; i < a.n; i++) /* fast: many pairs meet within a step */
        put(&a, i, 1 + rnd() * 198, 1 + rnd() * 198, 120 * rnd() - 60, 120 * rnd() - 60);
    world_init(&b, 8000, 200, 1);
    memcpy(b.x, a.x, (size_t)a.n * sizeof *a.x);
    memcpy(b.y, a.y, (size_t)a.n * sizeof *a.y);
    memcpy(b.vx, a.vx, (size_t)a.n * sizeof *a.vx);
    memcpy(b.vy, a.vy, (size_t)a.n * sizeof *a.vy);
    sim_stats sa = {0}, sb = {0};
    run_steps(&a, &reversed_variant, 3, &sa);
    sim_stepper *st = sim_stepper_create(&b, &reversed_parallel_variant, 3);
    CHECK(st != NULL);
    if (!st)
        return;
    for (int k = 0; k < 3; k++)
        CHECK_INT(sim_step(st, &b, &sb), 0);
    sim_stepper_destroy(st);
    CHECK(sa.candidates > 3 * 65536);
    CHECK_INT(particles_differing(&a, &b), 0);
    CHECK_U64(sb.candidates, sa.candidates);
    CHECK_U64(sb.pair_collisions, sa.pair_collisions);
    CHECK_U64(sb.wall_collisions, sa.wall_collisions);
    sim_world_free(&a);
    sim_world_free(&b);
}

/* ---- the greedy walk on a team ---- */

/* A finder of made-up candidates that stress the walk: each particle i pairs with i + d for a
 * few offsets d (so pairs are unique), with times from {0, 1/4, 1/2, 3/4, 1} picked by (i, j)
 * (mostly after its wall where a near-wall particle of walk_world takes part), so that equal
 * times are the rule and (i, j) decides; the first WALK_HUBS particles pair with every third
 * particle besides, so that many candidates share a particle. The near-wall particles of
 * walk_world have wall times 1/4 and 1/2: a pair at the same time comes before the wall. */
enum { WALK_N = 30000, WALK_HUBS = 8, WALK_HUB_STRIDE = 3 };
static const int32_t walk_offsets[] = {1, 2, 3, 7, 16, 41, 97, 211};

static double walk_time(int32_t i, int32_t j)
{
    const uint32_t h = (((uint32_t)i * 73856093u) ^ ((uint32_t)j * 19349663u)) >> 8;
    if (i % 8 == 0 || j % 8 == 0) /* a near-wall particle's: 1/4 (its wall's time or before) for
                                     * one in 8, else 1/2, 3/4 or 1 */
        return h % 8 ? (double)(2 + h % 3) / 4 : 0.25;
    return (double)(h % 5) / 4;
}

/* Every candidate of walk_world's finder, in any order, through emit. */
static void walk_pairs(int32_t n, void (*emit)(void *ctx, sim_real t, int32_t i, int32_t j),
                       void *ctx)
{
    for (int32_t i = 0; i < n; i++)
        for (size_t k = 0; k < sizeof walk_offsets / sizeof *walk_offsets; k++)
            if (i + walk_offsets[k] < n)
                emit(ctx, walk_time(i, i + walk_offsets[k]), i, i + walk_offsets[k]);
    for (int32_t h = 0; h < WALK_HUBS; h++)
        for (int32_t j = 300 + h; j < n; j += WALK_HUB_STRIDE)
            emit(ctx, walk_time(h, j), h, j);
}

static void emit_to_sink(void *ctx, sim_real t, int32_t i, int32_t j)
{
    sim_pair_sink *sink = ctx;
    sim_cand_buf *buf = sim_sink_buf(sink, (int)((uint32_t)(i ^ j) % (uint32_t)sink->count));
    buf->pair_tests++;
    sim_cand_push(buf, t, i, j);
}

static void find_walk_pairs(const sim_world *w, sim_pair_sink *sink)
{
    walk_pairs(w->n, emit_to_sink, sink);
}

static const sim_variant walk_variant = {
    .name = "walk", .exact = true, .parallel = true, .find_pairs = find_walk_pairs,
};

/* Slow particles away from the walls (no wall within a step), and every 8th next to the right
 * wall moving into it at a wall time of exactly 1/2 or 1/4: about half of those walls lose
 * their particle to a pair, the last of a thread's wall buffer among them. */
static void walk_world(sim_world *w)
{
    world_init(w, WALK_N, 1000, 1);
    for (int32_t i = 0; i < WALK_N; i++) {
        const double y = 100 + 800 * rnd();
        if (i % 8 == 0)
            put(w, i, i % 16 ? 998.75 : 998.5, y, 1, 0);
        else
            put(w, i, 100 + 800 * rnd(), y, 2 * rnd() - 1, 2 * rnd() - 1);
    }
}

/* SPEC §2's resolution as written, for walk_world's first step: every candidate, the walls
 * included, sorted by the key (spec_key_cmp) and walked once. */
typedef struct walk_list {
    sim_cand *items;
    size_t len;
} walk_list;

static void emit_to_list(void *ctx, sim_real t, int32_t i, int32_t j)
{
    walk_list *l = ctx;
    l->items[l->len++] = (sim_cand){.t = t, .i = i, .j = j};
}

/* The first step's accepted collisions of each particle of w by the spec's walk: pcoll and
 * wcoll (0 or 1 each); returns the pairs that no wall comes first for. */
static size_t spec_walk(const sim_world *w, int64_t *pcoll, int64_t *wcoll)
{
    const size_t most = (size_t)w->n * (sizeof walk_offsets / sizeof *walk_offsets + 1) +
                        (size_t)WALK_HUBS * ((size_t)w->n / WALK_HUB_STRIDE + 1);
    walk_list l = {malloc(most * sizeof *l.items), 0};
    if (!l.items) {
        fprintf(stderr, "test_core: out of memory\n");
        exit(1);
    }
    walk_pairs(w->n, emit_to_list, &l);
    size_t kept = 0;
    for (size_t k = 0; k < l.len; k++)
        kept += !(sim_wall_time(w, l.items[k].i) < l.items[k].t ||
                  sim_wall_time(w, l.items[k].j) < l.items[k].t);
    for (int32_t i = 0; i < w->n; i++)
        if (sim_wall_time(w, i) <= 1)
            l.items[l.len++] = (sim_cand){.t = sim_wall_time(w, i), .i = i, .j = SIM_WALL};
    qsort(l.items, l.len, sizeof *l.items, spec_key_cmp);
    unsigned char *taken = calloc((size_t)w->n, 1);
    if (!taken) {
        fprintf(stderr, "test_core: out of memory\n");
        exit(1);
    }
    for (int32_t i = 0; i < w->n; i++)
        pcoll[i] = wcoll[i] = 0;
    for (size_t k = 0; k < l.len; k++) {
        const sim_cand c = l.items[k];
        if (taken[c.i] || (c.j != SIM_WALL && taken[c.j]))
            continue;
        taken[c.i] = 1;
        if (c.j == SIM_WALL) {
            wcoll[c.i] = 1;
        } else {
            taken[c.j] = 1;
            pcoll[c.i] = pcoll[c.j] = 1;
        }
    }
    free(taken);
    free(l.items);
    return kept;
}

/* Above SIM_RESOLVE_TEAM_MIN pairs a parallel stepper walks on its team (a walker and filters
 * ahead of it); its steps must be one thread's, whatever the team's timing, and its first step
 * the spec's walk: many ties in t, pairs sharing particles, pairs tied with walls. */
static void test_step_team_walk(void)
{
    sim_world first;
    walk_world(&first);
    int64_t *pcoll = malloc(WALK_N * sizeof *pcoll), *wcoll = malloc(WALK_N * sizeof *wcoll);
    CHECK(pcoll && wcoll);
    if (!pcoll || !wcoll) {
        free(pcoll);
        free(wcoll);
        sim_world_free(&first);
        return;
    }
    CHECK(spec_walk(&first, pcoll, wcoll) >= SIM_RESOLVE_TEAM_MIN);
    int64_t pairs = 0, walls = 0;
    for (int32_t i = 0; i < WALK_N; i++) {
        pairs += pcoll[i];
        walls += wcoll[i];
    }
    CHECK(pairs > WALK_N / 2 && walls > 1000);
    sim_world one; /* the reference for later steps: one thread's serial walk */
    for (int threads = 1; threads <= 4; threads++) {
        for (int steps = 1; steps <= 3; steps += 2) {
            sim_world w;
            walk_world(&w);
            for (int32_t i = 0; i < WALK_N; i++) /* walk_world draws its state afresh */
                put(&w, i, first.x[i], first.y[i], first.vx[i], first.vy[i]);
            sim_stats st = {0};
            sim_stepper *s = sim_stepper_create(&w, &walk_variant, threads);
            CHECK(s != NULL);
            for (int k = 0; s && k < steps; k++)
                CHECK_INT(sim_step(s, &w, &st), 0);
            sim_stepper_destroy(s);
            if (steps == 1) {
                int32_t wrong = 0;
                for (int32_t i = 0; i < WALK_N; i++)
                    wrong += w.pcoll[i] != pcoll[i] || w.wcoll[i] != wcoll[i];
                CHECK_INT(wrong, 0);
                sim_world_free(&w);
            } else if (threads == 1) {
                one = w;
            } else {
                CHECK_INT(particles_differing(&w, &one), 0);
                sim_world_free(&w);
            }
        }
    }
    sim_world_free(&one);
    sim_world_free(&first);
    free(pcoll);
    free(wcoll);
}

/* The test finder, run by a parallel stepper: its wall candidates come from its threads. */
static const sim_variant parallel_variant = {
    .name = "parallel", .exact = true, .parallel = true, .find_pairs = find_all_pairs,
};

/* A stepper keeps the wall candidates its motion loop found for the next step (one buffer per
 * thread). Stepping on with them must give what a fresh stepper gives, which finds the walls
 * of the state it is handed: the same world stepped by one 3-thread stepper (enough particles
 * for the parallel loops) and by a new 1-thread stepper each step. */
static void test_step_carries_wall_candidates(void)
{
    enum { N = 5000, STEPS = 4 };
    sim_world a, b;
    dense_world(&a, N, 300);
    world_init(&b, N, 300, 1);
    for (int32_t i = 0; i < N; i++)
        put(&b, i, a.x[i], a.y[i], a.vx[i], a.vy[i]);
    sim_stats sa = {0}, sb = {0};
    sim_stepper *s = sim_stepper_create(&a, &parallel_variant, 3);
    CHECK(s != NULL);
    for (int k = 0; s && k < STEPS; k++)
        CHECK_INT(sim_step(s, &a, &sa), 0);
    sim_stepper_destroy(s);
    for (int k = 0; k < STEPS; k++)
        run_steps(&b, &sim_variant_def, 1, &sb);
    CHECK_INT(particles_differing(&a, &b), 0);
    CHECK_U64(sa.candidates, sb.candidates);
    CHECK_U64(sa.wall_collisions, sb.wall_collisions);
    CHECK(sa.wall_collisions > 20);
    sim_world_free(&a);
    sim_world_free(&b);
}

/* The wall times of the stepper's vectorised wall pass are sim_wall_time's, bit for bit, on one
 * thread and on a team (each thread its own blocks), for the cases the scalar form singles out:
 * velocities of +0 and -0 on either axis, at rest, centres on a wall moving in or out, corners;
 * among particles that move anywhere and collide. */
static void test_step_wall_times_are_scalar(void)
{
    enum { N = 5000 };
    static const double special[][4] = {
        {50, 50, 0, 0},        {50, 50, -0.0, 0}, {50, 50, 0, -0.0},  {1, 50, -1, 0},
        {1, 50, 1, 0},         {299, 50, 0.5, 0}, {299, 50, -0.5, 0}, {150, 1, 0, -2},
        {150, 299, -0.0, 3},   {298.5, 298.5, 1, 1}, {1, 1, -1, -1},  {2, 298, -4, 2},
    };
    enum { SPECIAL = sizeof special / sizeof special[0] };
    for (int threads = 1; threads <= 3; threads += 2) {
        sim_world w;
        dense_world(&w, N, 300);
        for (int32_t k = 0; k < SPECIAL; k++) /* spread over the blocks of the pass */
            put(&w, k * (N / SPECIAL), special[k][0], special[k][1], special[k][2],
                special[k][3]);
        sim_stats st = {0};
        sim_stepper *s = sim_stepper_create(&w, &parallel_variant, threads);
        CHECK(s != NULL);
        for (int step = 0; s && step < 2; step++) {
            CHECK_INT(sim_step(s, &w, &st), 0);
            int32_t differ = 0;
            for (int32_t i = 0; i < N; i++) {
                const sim_real got = sim_stepper_wall_time(s, i), want = sim_wall_time(&w, i);
                differ += memcmp(&got, &want, sizeof got) != 0;
            }
            CHECK_INT(differ, 0);
        }
        sim_stepper_destroy(s);
        sim_world_free(&w);
    }
}

/* --timing's phase split: every phase is timed (>= 0, and the finder, sorting,
 * resolution and motion of a scene with collisions take some time over 20 steps) and the
 * phases together fit inside the time spent in sim_step, on one thread and on three. */
static void test_step_phase_times(void)
{
    for (int threads = 1; threads <= 3; threads += 2) {
        enum { N = 5000, STEPS = 4 };
        sim_world w;
        dense_world(&w, N, 300);
        sim_stats st = {0};
        sim_stepper *s = sim_stepper_create(&w, &parallel_variant, threads);
        CHECK(s != NULL);
        const double t0 = omp_get_wtime();
        for (int k = 0; s && k < STEPS; k++)
            CHECK_INT(sim_step(s, &w, &st), 0);
        const double stepping = omp_get_wtime() - t0;
        sim_stepper_destroy(s);
        const double phases[] = {st.broad_s, st.walls_s, st.sort_s, st.resolve_s, st.motion_s};
        double sum = 0;
        for (size_t k = 0; k < sizeof phases / sizeof *phases; k++) {
            CHECK(phases[k] >= 0);
            sum += phases[k];
        }
        CHECK(st.broad_s > 0 && st.sort_s > 0 && st.motion_s > 0 && st.walls_s > 0);
        CHECK(st.pair_collisions > 0 && st.wall_collisions > 0);
        CHECK(sum <= stepping);
        sim_world_free(&w);
    }
}

/* ---- the moves of accepted collisions, against SPEC §2 written out as scalar code ---- */

static double ref_axis_time(double q, double w, double lo, double hi)
{
    if (w > 0)
        return (hi - q) / w;
    if (w < 0)
        return (lo - q) / w;
    return HUGE_VAL;
}

static double ref_wall(double w, double lo, double hi)
{
    return w > 0 ? hi : lo;
}

static double ref_clamp(double q, double lo, double hi)
{
    return q < lo ? lo : (q > hi ? hi : q);
}

/* SPEC §2 finish(rest), then the clamp into the box. */
static void ref_finish(double *x, double *y, double vx, double vy, double rest, double lo,
                       double hi)
{
    double tx = ref_axis_time(*x, vx, lo, hi), ty = ref_axis_time(*y, vy, lo, hi);
    if (tx < 0)
        tx = 0;
    if (ty < 0)
        ty = 0;
    const double tw = tx < ty ? tx : ty;
    if (tw < rest) {
        *x += tw * vx;
        *y += tw * vy;
        if (tx == tw)
            *x = ref_wall(vx, lo, hi);
        if (ty == tw)
            *y = ref_wall(vy, lo, hi);
    } else {
        *x += rest * vx;
        *y += rest * vy;
    }
    *x = ref_clamp(*x, lo, hi);
    *y = ref_clamp(*y, lo, hi);
}

/* Particle i's new state (x, y, vx, vy) after its accepted collision with e (SIM_WALL or the
 * partner) at t, from the state of w, as SPEC §2 words it for one particle. */
static void ref_move(const sim_world *w, int32_t i, int32_t e, double t, double out[4])
{
    const double lo = w->lo, hi = w->hi;
    double x = w->x[i], y = w->y[i], vx = w->vx[i], vy = w->vy[i];
    if (e == SIM_WALL) {
        const double tx = ref_axis_time(x, vx, lo, hi), ty = ref_axis_time(y, vy, lo, hi);
        x += t * vx;
        y += t * vy;
        if (tx == t) {
            x = ref_wall(vx, lo, hi);
            vx = -vx;
        }
        if (ty == t) {
            y = ref_wall(vy, lo, hi);
            vy = -vy;
        }
    } else {
        const int32_t a = i < e ? i : e, b = i < e ? e : i;
        const double xa = w->x[a] + t * w->vx[a], ya = w->y[a] + t * w->vy[a];
        const double xb = w->x[b] + t * w->vx[b], yb = w->y[b] + t * w->vy[b];
        const double dx = xb - xa, dy = yb - ya, dist = sqrt(dx * dx + dy * dy);
        x += t * vx;
        y += t * vy;
        if (dist > 0) {
            const double nx = dx / dist, ny = dy / dist;
            const double ua = w->vx[a] * nx + w->vy[a] * ny;
            const double ub = w->vx[b] * nx + w->vy[b] * ny;
            const double du = i == a ? ub - ua : ua - ub;
            vx = vx + du * nx;
            vy = vy + du * ny;
        }
    }
    ref_finish(&x, &y, vx, vy, 1 - t, lo, hi);
    out[0] = x;
    out[1] = y;
    out[2] = vx;
    out[3] = vy;
}

/* sim_move_walls and sim_move_pairs give, bit for bit, what the scalar SPEC code gives, on
 * random events in partial and full blocks: fast and slow particles, particles on a wall or in
 * a corner, zero and -0.0 velocity components, t = 0 and t = 1, a pair with no normal
 * (coincident centres at t). */
static void test_event_moves_match_scalar_spec(void)
{
    enum { N = 3000 };
    sim_world w, before;
    world_init(&w, N, 100, 1);
    world_init(&before, N, 100, 1);
    for (int32_t i = 0; i < N; i++) {
        const double speed = rnd() < 0.5 ? 3 : 80;
        double x = 1 + rnd() * 98, y = 1 + rnd() * 98;
        double vx = speed * (2 * rnd() - 1), vy = speed * (2 * rnd() - 1);
        const double kind = rnd();
        if (kind < 0.1)
            x = rnd() < 0.5 ? 1 : 99;
        else if (kind < 0.15)
            x = y = 99;
        if (rnd() < 0.1)
            vx = rnd() < 0.5 ? 0.0 : -0.0;
        if (rnd() < 0.05)
            vy = rnd() < 0.5 ? 0.0 : -0.0;
        put(&w, i, x, y, vx, vy);
    }
    /* Particles 0-1: coincident at t = 0.5 (no normal). */
    put(&w, 0, 50, 50, 1, 0);
    put(&w, 1, 51, 50, -1, 0);
    sim_world_free(&before);
    world_init(&before, N, 100, 1);
    for (int32_t i = 0; i < N; i++)
        put(&before, i, w.x[i], w.y[i], w.vx[i], w.vy[i]);
    /* Events over disjoint particles: pairs (2k, 2k+1) for the first third, walls (those
     * whose wall time is within the step) among the rest. */
    static sim_cand walls[N], pairs[N];
    size_t nw = 0, np = 0;
    for (int32_t i = 0; i + 1 < N / 3; i += 2) {
        const double u = rnd();
        const double t = i == 0 ? 0.5 : u < 0.05 ? 0.0 : u < 0.1 ? 1.0 : rnd();
        pairs[np++] = (sim_cand){t, i, i + 1};
    }
    for (int32_t i = N / 3; i < N; i++) {
        const sim_real t = sim_wall_time(&w, i);
        if (t <= 1)
            walls[nw++] = (sim_cand){t, i, SIM_WALL};
    }
    CHECK(nw > 500 && np > 400);
    static sim_real nx[N], ny[N], out[SIM_PAIR_OUT * N];
    const size_t block = sim_event_block();
    CHECK(block > 0);
    for (size_t k0 = 0; k0 < nw; k0 += block)
        sim_move_walls(&w, walls, nw, k0, nx, ny);
    for (size_t k0 = 0; k0 < np; k0 += block)
        sim_move_pairs(&w, pairs, np, k0, out, NULL, NULL);
    /* sim_move_pairs changes nothing in the world: its partners' velocities are still the old
     * ones until copied from out, as sim_step does. */
    int kept = 0;
    for (size_t k = 0; k < np; k++) {
        kept += w.vx[pairs[k].i] == before.vx[pairs[k].i] &&
                w.vx[pairs[k].j] == before.vx[pairs[k].j];
        for (int side = 0; side < 2; side++) {
            const int32_t i = side ? pairs[k].j : pairs[k].i;
            const sim_real *o = out + SIM_PAIR_OUT * k + 4 * side;
            nx[i] = o[0];
            ny[i] = o[1];
            w.vx[i] = o[2];
            w.vy[i] = o[3];
        }
    }
    CHECK_INT(kept, (int)np);
    /* Without out, the pairs' new states go straight into nx, ny and the world's velocities:
     * the same bits. */
    sim_world direct;
    world_init(&direct, N, 100, 1);
    for (int32_t i = 0; i < N; i++)
        put(&direct, i, before.x[i], before.y[i], before.vx[i], before.vy[i]);
    static sim_real dnx[N], dny[N];
    for (size_t k0 = 0; k0 < np; k0 += block)
        sim_move_pairs(&direct, pairs, np, k0, NULL, dnx, dny);
    int same = 0;
    for (size_t k = 0; k < np; k++)
        for (int side = 0; side < 2; side++) {
            const int32_t i = side ? pairs[k].j : pairs[k].i;
            same += !memcmp(&dnx[i], &nx[i], sizeof nx[i]) &&
                    !memcmp(&dny[i], &ny[i], sizeof ny[i]) &&
                    !memcmp(&direct.vx[i], &w.vx[i], sizeof w.vx[i]) &&
                    !memcmp(&direct.vy[i], &w.vy[i], sizeof w.vy[i]);
        }
    CHECK_INT(same, 2 * (int)np);
    sim_world_free(&direct);
    int differ = 0, turned = 0;
    for (size_t k = 0; k < nw + np; k++) {
        const sim_cand c = k < nw ? walls[k] : pairs[k - nw];
        for (int side = 0; side < (c.j == SIM_WALL ? 1 : 2); side++) {
            const int32_t i = side ? c.j : c.i, e = c.j == SIM_WALL ? SIM_WALL : side ? c.i : c.j;
            double want[4];
            ref_move(&before, i, e, c.t, want);
            const double got[4] = {nx[i], ny[i], w.vx[i], w.vy[i]};
            differ += memcmp(got, want, sizeof got) != 0;
            turned += want[2] != before.vx[i] || want[3] != before.vy[i];
        }
    }
    CHECK_INT(differ, 0);
    CHECK(turned > 1000);
    /* The pair without a normal keeps its velocities. */
    CHECK_REAL(w.vx[0], 1);
    CHECK_REAL(w.vx[1], -1);
    sim_world_free(&w);
    sim_world_free(&before);
}

/* sim_team_spread moves each thread once and hands it back the process's whole mask: every
 * thread of a later team may run on every CPU the process could before. Team sizes of 2, the
 * CPU count (both of sim_team.c's regions run) and one more (the second alone). */
static void test_team_spread_restores_the_mask(void)
{
#if defined(__linux__)
    cpu_set_t before;
    CPU_ZERO(&before);
    CHECK_INT(sched_getaffinity(0, sizeof before, &before), 0);
    const int cpus = CPU_COUNT(&before);
    const int sizes[] = {2, cpus > 2 ? cpus : 3, (cpus > 2 ? cpus : 3) + 1};
    for (size_t k = 0; k < sizeof sizes / sizeof sizes[0]; k++) {
        sim_team_spread(sizes[k]);
        int differ = 0;
#pragma omp parallel num_threads(sizes[k]) reduction(+ : differ)
        {
            cpu_set_t now;
            CPU_ZERO(&now);
            differ += sched_getaffinity(0, sizeof now, &now) != 0 || !CPU_EQUAL(&now, &before);
        }
        CHECK_INT(differ, 0);
    }
#endif
}

/* The 4-body tie resolves by (i, j): (0,1) and (2,3) collide (scenes/tie4.md). */
static void test_step_tie_order(void)
{
    sim_world w;
    world_init(&w, 4, 100, 1);
    put(&w, 0, 10, 10, 1, 1);
    put(&w, 1, 13, 10, -1, 1);
    put(&w, 2, 10, 13, 1, -1);
    put(&w, 3, 13, 13, -1, -1);
    run_steps(&w, &sim_variant_def, 1, NULL);
    static const double want[4][4] = {
        {10, 11, -1, 1}, {13, 11, 1, 1}, {10, 12, -1, -1}, {13, 12, 1, -1}};
    for (int32_t i = 0; i < 4; i++) {
        CHECK_REAL(w.x[i], want[i][0]);
        CHECK_REAL(w.y[i], want[i][1]);
        CHECK_REAL(w.vx[i], want[i][2]);
        CHECK_REAL(w.vy[i], want[i][3]);
        CHECK_INT(w.pcoll[i], 1);
    }
    sim_world_free(&w);
}

/* One pair collision conserves kinetic energy and momentum up to a few ulps of the pair's:
 * the normal n = d/|d| has |n|^2 = 1 + delta with |delta| <= ~8u (u = 2^-53), which changes
 * the energy by 2 (u_j - u_i)^2 delta <= 32u KE_pair; the rounding of du (computed once,
 * shared exactly by both partners, since fl(ua - ub) = -fl(ub - ua)) adds <= ~16u KE_pair and
 * the final additions <= ~4u KE_pair. Bound used: 64u = 32 eps, here and in run_scenes.sh. */
static void test_step_collision_conserves(void)
{
    sim_world w;
    world_init(&w, 2, 1000, 1);
    int collisions = 0, bad_e = 0, bad_p = 0;
    double worst = 0;
    for (int k = 0; k < 20000; k++) {
        random_pair(&w, 0, 1);
        w.pcoll[0] = w.pcoll[1] = w.wcoll[0] = w.wcoll[1] = 0;
        const double e0 = energy(&w);
        const double px = w.vx[0] + w.vx[1], py = w.vy[0] + w.vy[1];
        const double speed = fabs(w.vx[0]) + fabs(w.vy[0]) + fabs(w.vx[1]) + fabs(w.vy[1]);
        run_steps(&w, &sim_variant_def, 1, NULL);
        if (w.pcoll[0] != 1)
            continue;
        collisions++;
        const double rel = e0 > 0 ? fabs(energy(&w) - e0) / e0 : 0;
        worst = rel > worst ? rel : worst;
        bad_e += !(rel <= 32 * 0x1p-52);
        bad_p += !(fabs(w.vx[0] + w.vx[1] - px) <= 8 * 0x1p-52 * speed &&
                   fabs(w.vy[0] + w.vy[1] - py) <= 8 * 0x1p-52 * speed);
    }
    CHECK(collisions > 1000);
    CHECK_INT(bad_e, 0);
    CHECK_INT(bad_p, 0);
    if (bad_e)
        printf("  (worst relative energy change %.3g)\n", worst);
    sim_world_free(&w);
}

/* ---- the runner ---- */

/* Under the ASan+UBSan build a sanitizer error ends the process at once: a stack trace names
 * the test it happened in. (Hooks the sanitizer runtimes read; unused in the plain build.) */
const char *__ubsan_default_options(void);
const char *__ubsan_default_options(void)
{
    return "print_stacktrace=1";
}

#define TEST(f) {#f, f}

/* Pure functions first, then tests that step a world. */
static const test_case tests[] = {
    TEST(test_splitmix64_seed1),
    TEST(test_splitmix64_seed0_and_wraparound),
    TEST(test_uniform_seed1),
    TEST(test_generate_seed1),
    TEST(test_generate_skips_listed),
    TEST(test_generate_ranges),
    TEST(test_generate_chunks_are_one_stream),
    TEST(test_parse_header_ok),
    TEST(test_parse_header_errors),
    TEST(test_parse_particles_ok),
    TEST(test_parse_particles_errors),
    TEST(test_wall_time),
    TEST(test_pair_time_cases),
    TEST(test_pair_time_is_spec_formula),
    TEST(test_scan_row_matches_pair_time),
    TEST(test_scan_row_grazing_alone),
    TEST(test_row_tiles),
    TEST(test_cand_push_grows),
    TEST(test_world_alloc),
    TEST(test_sort_candidates_matches_the_spec_key),
    TEST(test_format_real),
    TEST(test_fixed8_matches_printf),
    TEST(test_write_blocks),
    TEST(test_write_blocks_on_a_team),
    TEST(test_describe_json),
    TEST(test_step_head_on),
    TEST(test_step_pair_before_wall),
    TEST(test_step_at_wall_moving_in),
    TEST(test_step_tie_order),
    TEST(test_step_stats),
    TEST(test_step_order_independent),
    TEST(test_step_team_sort),
    TEST(test_step_team_walk),
    TEST(test_step_carries_wall_candidates),
    TEST(test_step_wall_times_are_scalar),
    TEST(test_step_phase_times),
    TEST(test_event_moves_match_scalar_spec),
    TEST(test_team_spread_restores_the_mask),
    TEST(test_step_collision_conserves),
    TEST(test_step_empty_world),
};

int main(int argc, char **argv)
{
    return run_tests(tests, TEST_COUNT(tests), argc, argv);
}
