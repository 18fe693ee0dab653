/*
 * student.c: a small implementation of the assignment written as a student would (not in the
 * core's style), to test the harness's grading of programs (tests/runner/test_grading.py). One
 * source, many programs: compiled as is it follows SPEC; -DREAL=float or -DLONG_DOUBLE
 * and -DORDER compute the same rules differently (correct programs); each -DBUG_* breaks one
 * rule:
 *
 *   BUG_DOUBLE   a pair is accepted when its first particle is free: the second may collide twice
 *   BUG_NOSTOP   after its collision a particle is not stopped at the wall it meets
 *   BUG_TIE      a wall before a pair at the same time
 *   BUG_CORNER   walls ignored for a particle in a corner region (within L/8 of two walls)
 *   BUG_AXIS     a collision swaps the x components of the velocities, not the normal ones
 *   BUG_FEWER    one step too few (the last state printed twice)
 *   BUG_RACE     the pair loop's temporaries are shared by its threads (declared outside it)
 *   BUG_BEFORE   prints the positions from before the step with the velocities after it
 *   BUG_SLIP     particle 7's x printed 0.5 too large from step 2 on
 *
 * Usage: student THREADS INPUT; prints every step with %.6f.
 */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <omp.h>
#include <sched.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#if defined(LONG_DOUBLE)
#define REAL long double
#elif !defined(REAL)
#define REAL double
#endif
typedef REAL real;

typedef struct { real t; int i, j; } cand; /* j = -1: wall */

static int n, S;
static real L, r, *x, *y, *vx, *vy, *nx, *ny, *ox, *oy;
static long *pc, *wc;
static cand *cands;
static long ncand, capcand;

static int cmp(const void *a, const void *b)
{
    const cand *p = a, *q = b;
    if (p->t != q->t) return p->t < q->t ? -1 : 1;
    int pw = p->j < 0, qw = q->j < 0;
#ifdef BUG_TIE
    pw = !pw; qw = !qw;
#endif
    if (pw != qw) return pw - qw;
    if (p->i != q->i) return p->i - q->i;
    return p->j - q->j;
}

static void push(real t, int i, int j)
{
    long k;
#pragma omp atomic capture
    k = ncand++;
    cands[k] = (cand){t, i, j};
}

static real wall_time(real q, real w)
{
    if (w > 0) return (L - r - q) / w;
    if (w < 0) return (r - q) / w;
    return INFINITY;
}

#ifdef BUG_CORNER
static int in_corner(int i)
{
    real m = L / 8;
    int nearx = x[i] < m || x[i] > L - m, neary = y[i] < m || y[i] > L - m;
    return nearx && neary;
}
#endif

static void finish(int i, real rest)
{
    real tx = wall_time(nx[i], vx[i]), ty = wall_time(ny[i], vy[i]);
    real tw = tx < ty ? tx : ty;
    if (tw < 0) tw = 0;
#ifdef BUG_NOSTOP
    tw = INFINITY;
#endif
    if (tw < rest) {
        nx[i] += tw * vx[i]; ny[i] += tw * vy[i];
        if (tx == tw) nx[i] = vx[i] > 0 ? L - r : r;
        if (ty == tw) ny[i] = vy[i] > 0 ? L - r : r;
    } else {
        nx[i] += rest * vx[i]; ny[i] += rest * vy[i];
    }
}

static real clampr(real q) { return q < r ? r : q > L - r ? L - r : q; }

static void step(void)
{
    ncand = 0;
    for (int i = 0; i < n; i++) {
        real tx = wall_time(x[i], vx[i]), ty = wall_time(y[i], vy[i]);
        real tw = tx < ty ? tx : ty;
#ifdef BUG_CORNER
        if (in_corner(i)) continue;
#endif
        if (tw <= 1) push(tw, i, -1);
    }
    real d = 2 * r;
#pragma omp parallel for schedule(dynamic)
    for (int i = 0; i < n; i++)
        for (int j = i + 1; j < n; j++) {
#if defined(BUG_RACE)
            static volatile real dx, dy, Dx, Dy, b, c, a, cross, disc;
            dx = x[j] - x[i]; dy = y[j] - y[i]; Dx = vx[j] - vx[i]; Dy = vy[j] - vy[i];
            b = dx * Dx + dy * Dy;
            if (b >= 0) continue;
            /* More work here, as students do; giving the core away makes the other thread
             * overwrite the shared temporaries even where the two share one core. */
            sched_yield();
            c = (dx * dx + dy * dy) - d * d;
            if (c < 0) continue;
            a = Dx * Dx + Dy * Dy;
            cross = dx * Dy - dy * Dx;
            disc = d * d * a - cross * cross;
#elif defined(ORDER)
            real dx = x[i] - x[j], dy = y[i] - y[j], Dx = vx[i] - vx[j], Dy = vy[i] - vy[j];
            real b = Dx * dx + Dy * dy;
            if (b >= 0) continue;
            real c = dy * dy + dx * dx - d * d;
            if (c < 0) continue;
            real a = Dy * Dy + Dx * Dx;
            real cross = Dx * dy - Dy * dx;
            real disc = a * (d * d) - cross * cross;
#else
            real dx = x[j] - x[i], dy = y[j] - y[i], Dx = vx[j] - vx[i], Dy = vy[j] - vy[i];
            real b = dx * Dx + dy * Dy;
            if (b >= 0) continue;
            real c = (dx * dx + dy * dy) - d * d;
            if (c < 0) continue;
            real a = Dx * Dx + Dy * Dy;
            real cross = dx * Dy - dy * Dx;
            real disc = d * d * a - cross * cross;
#endif
            if (disc < 0) continue;
            real t = c / (-b + sqrt(disc));
            if (t <= 1) push(t, i, j);
        }
    qsort(cands, (size_t)ncand, sizeof *cands, cmp);
    char *taken = calloc((size_t)n, 1);
    for (int i = 0; i < n; i++) { nx[i] = x[i] + vx[i]; ny[i] = y[i] + vy[i]; }
    for (long k = 0; k < ncand; k++) {
        cand c = cands[k];
        if (c.j < 0) {
            if (taken[c.i]) continue;
            taken[c.i] = 1;
            wc[c.i]++;
            int i = c.i;
            real tx = wall_time(x[i], vx[i]), ty = wall_time(y[i], vy[i]);
            nx[i] = x[i] + c.t * vx[i]; ny[i] = y[i] + c.t * vy[i];
            if (tx == c.t) { nx[i] = vx[i] > 0 ? L - r : r; vx[i] = -vx[i]; }
            if (ty == c.t) { ny[i] = vy[i] > 0 ? L - r : r; vy[i] = -vy[i]; }
            finish(i, 1 - c.t);
            continue;
        }
#ifdef BUG_DOUBLE
        if (taken[c.i]) continue;
#else
        if (taken[c.i] || taken[c.j]) continue;
#endif
        taken[c.i] = taken[c.j] = 1;
        pc[c.i]++; pc[c.j]++;
        int i = c.i, j = c.j;
        real xi = x[i] + c.t * vx[i], yi = y[i] + c.t * vy[i];
        real xj = x[j] + c.t * vx[j], yj = y[j] + c.t * vy[j];
        nx[i] = xi; ny[i] = yi; nx[j] = xj; ny[j] = yj;
#ifdef BUG_AXIS
        real s = vx[i]; vx[i] = vx[j]; vx[j] = s;
#else
        real ex = xj - xi, ey = yj - yi, len = sqrt(ex * ex + ey * ey);
        ex /= len; ey /= len;
        real ui = vx[i] * ex + vy[i] * ey, uj = vx[j] * ex + vy[j] * ey;
        vx[i] += (uj - ui) * ex; vy[i] += (uj - ui) * ey;
        vx[j] += (ui - uj) * ex; vy[j] += (ui - uj) * ey;
#endif
        finish(i, 1 - c.t);
        finish(j, 1 - c.t);
    }
    free(taken);
    for (int i = 0; i < n; i++) {
        ox[i] = x[i]; oy[i] = y[i];
        x[i] = clampr(nx[i]); y[i] = clampr(ny[i]);
    }
}

static void print(int s, int final)
{
    for (int i = 0; i < n; i++) {
        double px = (double)x[i], py = (double)y[i];
#ifdef BUG_BEFORE
        if (s > 0) { px = (double)ox[i]; py = (double)oy[i]; }
#endif
#ifdef BUG_SLIP
        if (i == 7 && s >= 2) px += 0.5;
#endif
        printf("%d %d %.6f %.6f %.6f %.6f", s, i, px, py, (double)vx[i], (double)vy[i]);
        if (final) printf(" %ld %ld", pc[i], wc[i]);
        printf("\n");
    }
}

int main(int argc, char **argv)
{
    if (argc != 3) { fprintf(stderr, "usage: student THREADS INPUT\n"); return 2; }
    omp_set_num_threads(atoi(argv[1]));
    FILE *f = fopen(argv[2], "r");
    char mode[16];
    double Ld, rd;
    if (!f || fscanf(f, "%d %lf %lf %d %15s", &n, &Ld, &rd, &S, mode) != 5) return 2;
    L = Ld; r = rd;
    x = calloc(n, sizeof *x); y = calloc(n, sizeof *y); vx = calloc(n, sizeof *vx);
    vy = calloc(n, sizeof *vy); nx = calloc(n, sizeof *nx); ny = calloc(n, sizeof *ny);
    ox = calloc(n, sizeof *ox); oy = calloc(n, sizeof *oy);
    pc = calloc(n, sizeof *pc); wc = calloc(n, sizeof *wc);
    capcand = (long)n * 8 + 64;
    cands = malloc((size_t)capcand * sizeof *cands);
    int i;
    double a, b, c, e;
    while (fscanf(f, "%d %lf %lf %lf %lf", &i, &a, &b, &c, &e) == 5) {
        x[i] = a; y[i] = b; vx[i] = c; vy[i] = e;
    }
    fclose(f);
    int print_mode = strcmp(mode, "print") == 0;
#ifdef BUG_FEWER
    int steps = S - 1;
#else
    int steps = S;
#endif
    for (int s = 0; s < steps; s++) {
        if (print_mode) print(s, 0);
        step();
    }
    if (print_mode && steps < S) print(S - 1, 0);
    print(S, 1);
    return 0;
}
