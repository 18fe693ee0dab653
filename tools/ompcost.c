/*
 * ompcost: what the OpenMP runtime charges for the operations the pair finders ask of it, at
 * one thread count, measured the way EPCC's syncbench does: batches of K operations timed by
 * the team's first thread, K grown until a batch takes BATCH_MIN_S, batches repeated until the
 * budget is spent, and the median over batches of a batch's seconds over its K operations.
 *
 *   region          an empty `omp parallel` of T threads: a team fork and its closing barrier
 *                   (p2 pays one per row, p1 one per step);
 *   barrier         an `omp barrier` inside a team of T;
 *   grab            one iteration of an empty `omp for schedule(dynamic, 1)` loop shared by T
 *                   threads: the loop's wall time over its iterations, at least
 *                   GRABS_PER_THREAD a thread (p2d pays one per pair test, p1d one per row);
 *   nested_region   an empty `omp parallel` of T threads forked by each thread of an outer team
 *                   of T at once (p3's team per row), the wall time over the forks of one outer
 *                   thread; null where T*T passes NESTED_MAX_THREADS.
 *
 * Prints one JSON line: {"threads":T,"region_ns":...,"barrier_ns":...,"grab_ns":...,
 * "nested_region_ns":...,"budget_ms":...}. The harness stores these per cell (harness.measure.
 * ompcost) and the report multiplies them by each strategy's operations per step.
 */
#include <errno.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <omp.h>

#define EXIT_USAGE 2
#define MAX_THREADS 4096         /* the variants' --threads bound */
#define NESTED_MAX_THREADS 1024  /* T*T threads at once: more is not measured */
#define DEFAULT_BUDGET_MS 100    /* per operation */
#define MAX_BUDGET_MS 600000
#define BATCH_MIN_S 2e-4         /* a batch long enough for the clock, short next to a tick */
#define MAX_OPS_PER_BATCH (1 << 20)
#define MIN_BATCHES 11
#define CALIBRATION_TRIES 3
/* A grab batch is one loop, and its closing barrier no grab: at least this many iterations a
 * thread spread it thin, even where the barrier waits milliseconds for a team sharing cores. */
#define GRABS_PER_THREAD 1024
#define MAX_BATCHES 201

/* Keeps an empty region or loop body from being optimised away, at no cost of its own. */
#define TOUCH() __asm__ __volatile__("" ::: "memory")

typedef double batch_fn(int threads, int ops);

static double region_batch(int threads, int ops)
{
    const double t0 = omp_get_wtime();
    for (int k = 0; k < ops; k++) {
#pragma omp parallel num_threads(threads)
        TOUCH();
    }
    return omp_get_wtime() - t0;
}

/* The batches inside a team run from the first thread's start to the last one's end: a
 * thread that waits for a CPU past the starting barrier, while the others work, must not shorten
 * the batch (the first thread's clock alone would). */
#define TEAM_BATCH(threads, BODY)                                                                \
    double first = 1e300, last = -1e300;                                                        \
    _Pragma("omp parallel num_threads(threads) reduction(min : first) reduction(max : last)")  \
    {                                                                                           \
        _Pragma("omp barrier");                                                                 \
        first = omp_get_wtime();                                                                \
        BODY;                                                                                   \
        last = omp_get_wtime();                                                                 \
    }                                                                                           \
    return last - first

static void barriers(int ops)
{
    for (int k = 0; k < ops; k++) {
#pragma omp barrier
    }
}

static double barrier_batch(int threads, int ops)
{
    TEAM_BATCH(threads, barriers(ops));
}

static void grabs(int ops)
{
#pragma omp for schedule(dynamic, 1)
    for (int k = 0; k < ops; k++)
        TOUCH();
}

static double grab_batch(int threads, int ops)
{
    TEAM_BATCH(threads, grabs(ops));
}

static void inner_regions(int threads, int ops)
{
    for (int k = 0; k < ops; k++) {
#pragma omp parallel num_threads(threads)
        TOUCH();
    }
}

static double nested_batch(int threads, int ops)
{
    TEAM_BATCH(threads, inner_regions(threads, ops));
}

static int by_value(const void *a, const void *b)
{
    const double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* The median seconds per operation of `batch` at `threads` within about `budget_s`, in
 * batches of at least `min_ops` operations. */
static double median_per_op(batch_fn *batch, int threads, int min_ops, double budget_s)
{
    /* K from the fastest of a few batches: one that waited for a CPU must not fix K at 1. */
    int ops = min_ops;
    while (ops < MAX_OPS_PER_BATCH) {
        double fastest = batch(threads, ops);
        for (int k = 1; k < CALIBRATION_TRIES; k++) {
            const double s = batch(threads, ops);
            fastest = s < fastest ? s : fastest;
        }
        if (fastest >= BATCH_MIN_S)
            break;
        ops *= 2;
    }
    double per_op[MAX_BATCHES];
    int count = 0;
    const double end = omp_get_wtime() + budget_s;
    while (count < MAX_BATCHES && (count < MIN_BATCHES || omp_get_wtime() < end))
        per_op[count++] = batch(threads, ops) / ops;
    qsort(per_op, (size_t)count, sizeof per_op[0], by_value);
    return count % 2 ? per_op[count / 2] : 0.5 * (per_op[count / 2 - 1] + per_op[count / 2]);
}

static const char USAGE[] =
    "usage: %s [--threads N] [--budget-ms MS]\n"
    "  The OpenMP runtime's cost of an empty parallel region, a barrier, a dynamic schedule's\n"
    "  chunk and a nested region at N threads (default: OMP_NUM_THREADS or the CPUs), each the\n"
    "  median over batches measured for about MS ms (default 100); one JSON line, in ns.\n";

static int usage_error(const char *name, const char *what, const char *arg)
{
    fprintf(stderr, "%s: usage: %s '%.64s' (try --help)\n", name, what, arg);
    return EXIT_USAGE;
}

static bool parse_int(const char *s, long max, long *out)
{
    if (*s < '0' || *s > '9')
        return false;
    char *end;
    errno = 0;
    const long v = strtol(s, &end, 10);
    if (errno == ERANGE || *end != '\0' || v < 1 || v > max)
        return false;
    *out = v;
    return true;
}

static void put_ns(const char *key, double seconds)
{
    printf(",\"%s\":%.6g", key, seconds * 1e9);
}

int main(int argc, char **argv)
{
    const char *name = "ompcost";
    long threads = 0, budget_ms = DEFAULT_BUDGET_MS;
    for (int k = 1; k < argc; k++) {
        const char *a = argv[k];
        if (strcmp(a, "--help") == 0 || strcmp(a, "-h") == 0) {
            printf(USAGE, name);
            return 0;
        }
        if (strcmp(a, "--threads") != 0 && strcmp(a, "--budget-ms") != 0)
            return usage_error(name, "unknown option", a);
        if (k + 1 == argc)
            return usage_error(name, "missing value after", a);
        const char *v = argv[++k];
        if (a[2] == 't' && !parse_int(v, MAX_THREADS, &threads))
            return usage_error(name, "--threads expects an integer in [1, 4096], got", v);
        if (a[2] == 'b' && !parse_int(v, MAX_BUDGET_MS, &budget_ms))
            return usage_error(name, "--budget-ms expects an integer in [1, 600000], got", v);
    }
    const int t = threads > 0 ? (int)threads : omp_get_max_threads();
    const double budget_s = (double)budget_ms / 1e3;
    omp_set_dynamic(0); /* every region gets the T threads it asks for */
    omp_set_max_active_levels(2);
    /* The team's threads are created once, outside every measured batch. */
    (void)region_batch(t, 1);
    printf("{\"threads\":%d", t);
    put_ns("region_ns", median_per_op(region_batch, t, 1, budget_s));
    put_ns("barrier_ns", median_per_op(barrier_batch, t, 1, budget_s));
    put_ns("grab_ns", median_per_op(grab_batch, t, GRABS_PER_THREAD * t, budget_s));
    if ((long)t * t <= NESTED_MAX_THREADS)
        put_ns("nested_region_ns", median_per_op(nested_batch, t, 1, budget_s));
    else
        fputs(",\"nested_region_ns\":null", stdout);
    printf(",\"budget_ms\":%ld}\n", budget_ms);
    return fflush(stdout) == 0 && !ferror(stdout) ? 0 : 1;
}
