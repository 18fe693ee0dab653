/*
 * sim_main.c: SPEC §5, the command line every variant shares. Links against one variant's
 * `sim_variant_def`; a variant file has no main() of its own.
 *
 * A variant that runs as several processes (sim_variant's `ranks`, an MPI variant) is started
 * and stopped here, through its hooks: every rank parses the command line and the input (rank 0
 * reads the input and shares it), runs the same steps on the same world, and rank 0 alone
 * writes the output and every message about the input or the command line, so that a run of
 * any number of ranks reads and writes what a run of one does.
 */
#include <errno.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <omp.h>

#include "sim_core.h"

/* stdout buffer: the size of the chunks sim_output.c formats lines into (SIM_OUT_CHUNK). glibc
 * still copies each chunk through it, but a buffer this small stays in the caches, where 1 MiB
 * cost 0.7 ms of the report benchmark's 1.96 ms of output (its page faults, and a copy to
 * cold memory); print mode's millions of lines still cost one write call per 64 KiB. */
#define SIM_STDOUT_BUFFER (64 * 1024)
/* Read chunk of the input. */
#define SIM_READ_CHUNK (1 << 16)
#define SIM_DEFAULT_SEED 1
/* How much of a command-line argument or a path a message quotes (bytes). */
#define SIM_ARG_QUOTE_MAX 200
/* The shortest line print mode writes ("0 0 1.00000000 1.00000000 0.00000000 0.00000000"),
 * for the bound on its output's size. */
#define SIM_PRINT_LINE_MIN 48

typedef struct sim_options {
    int threads; /* 0: OMP_NUM_THREADS / the runtime's default */
    uint64_t seed;
    bool precise, timing, help, describe, replay;
    const char *input; /* NULL: stdin */
} sim_options;

/* Seconds spent in each phase, and what was done, for --timing. */
typedef struct sim_report {
    double input_s, sim_s, output_s;
    sim_stats stats;
    sim_thread_work *work; /* per candidate writer (thread), `writers` of them; NULL if none */
    int writers;
} sim_report;

static const char *const usage_text =
    "usage: %s [--threads N] [--seed N] [--precise] [--timing] [INPUT]\n"
    "       %s --describe\n"
    "       %s --replay [--threads N] [STATES]\n"
    "  Simulate hard discs colliding in a square box (the model: docs/model.md).\n"
    "  Reads INPUT, or stdin when INPUT is absent or '-'.\n"
    "  --threads N  threads to use (overrides OMP_NUM_THREADS; ignored by seq)\n"
    "  --seed N     seed of the generator for particles the input does not list (default 1)\n"
    "  --precise    print reals with %%.17g instead of %%.8f\n"
    "  --timing     write one JSON line of timings and counts to stderr after the run\n"
    "  --describe   print what this variant is, as one line of JSON, and exit: name, summary\n"
    "               (how it finds candidate pairs), exact (output byte-identical to seq),\n"
    "               parallel (uses threads), all_pairs (tests every pair i < j with seq's\n"
    "               test), repairs (the seed strategy it repairs, or null), mpi (runs as MPI\n"
    "               ranks: `mpirun -np R VARIANT ...`, or alone as one; rank 0 reads and\n"
    "               writes), sync (its OpenMP operations per step, or null)\n"
    "  --replay     read states (`N L r`, then lines `k i x y vx vy [p]`, N per state) and\n"
    "               print each one's successor by this variant's rules, %%.17g, as lines\n"
    "               `k+1 i x y vx vy EVENT PARTNER T`; a binary input, binary output\n"
    "               (both binary forms: sim_replay.c)\n"
    "  --help       print this text\n";

/* Whether this process stays silent about the input and the command line: the ranks of an MPI
 * variant other than rank 0, which meet the same errors as rank 0 does (each parses the same
 * text), so that a run says each once. Failures of a rank's own (memory) it reports itself. */
static bool quiet;

/* A message about the input or the command line: one line on stderr, unless quiet. */
static void tell(const char *format, ...)
{
    if (quiet)
        return;
    va_list args;
    va_start(args, format);
    vfprintf(stderr, format, args);
    va_end(args);
}

/* An argument or a path as a message may show it: escaped (sim_escape), at most
 * SIM_ARG_QUOTE_MAX bytes of it, then "...". */
typedef struct sim_shown {
    char text[SIM_ESCAPED_MAX(SIM_ARG_QUOTE_MAX) + 3];
} sim_shown;

static sim_shown shown(const char *s)
{
    sim_shown out;
    const size_t len = strlen(s), n = len < SIM_ARG_QUOTE_MAX ? len : SIM_ARG_QUOTE_MAX;
    const size_t k = sim_escape(out.text, sizeof out.text, s, n);
    if (n < len)
        memcpy(out.text + k, "...", 4);
    return out;
}

static int usage_error(const char *name, const char *what, const char *arg)
{
    tell("%s: usage: %s '%s' (try --help)\n", name, what, shown(arg).text);
    return SIM_EXIT_USAGE;
}

static bool parse_u64(const char *s, uint64_t max, uint64_t *out)
{
    if (*s < '0' || *s > '9')
        return false;
    char *end;
    errno = 0;
    const unsigned long long v = strtoull(s, &end, 10);
    if (errno == ERANGE || *end != '\0' || v > max)
        return false;
    *out = v;
    return true;
}

/* Returns SIM_EXIT_OK or SIM_EXIT_USAGE (after printing the one-line error). */
static int parse_options(const char *name, int argc, char **argv, sim_options *o)
{
    *o = (sim_options){.seed = SIM_DEFAULT_SEED};
    for (int k = 1; k < argc; k++) {
        const char *a = argv[k];
        if (strcmp(a, "--help") == 0 || strcmp(a, "-h") == 0) {
            o->help = true;
        } else if (strcmp(a, "--describe") == 0) {
            o->describe = true;
        } else if (strcmp(a, "--replay") == 0) {
            o->replay = true;
        } else if (strcmp(a, "--precise") == 0) {
            o->precise = true;
        } else if (strcmp(a, "--timing") == 0) {
            o->timing = true;
        } else if (strcmp(a, "--threads") == 0 || strcmp(a, "--seed") == 0) {
            if (k + 1 == argc)
                return usage_error(name, "missing value after", a);
            const char *v = argv[++k];
            uint64_t value;
            if (a[2] == 't') {
                if (!parse_u64(v, 4096, &value) || value == 0)
                    return usage_error(name, "--threads expects an integer in [1, 4096], got", v);
                o->threads = (int)value;
            } else {
                if (!parse_u64(v, UINT64_MAX, &value))
                    return usage_error(name, "--seed expects an integer in [0, 2^64), got", v);
                o->seed = value;
            }
        } else if (a[0] == '-' && a[1] != '\0') {
            return usage_error(name, "unknown option", a);
        } else if (o->input) {
            return usage_error(name, "more than one INPUT:", a);
        } else {
            o->input = strcmp(a, "-") == 0 ? NULL : a;
            if (!o->input && k + 1 < argc && argv[k + 1][0] != '-')
                return usage_error(name, "more than one INPUT:", argv[k + 1]);
        }
    }
    return SIM_EXIT_OK;
}

/* The whole input, NUL-terminated. Returns NULL after printing why. */
static char *read_all(const char *name, const char *path, size_t *len)
{
    FILE *f = path ? fopen(path, "rb") : stdin;
    if (!f) {
        tell("%s: cannot read '%s': %s\n", name, shown(path).text, strerror(errno));
        return NULL;
    }
    size_t cap = SIM_READ_CHUNK, n = 0;
    char *buf = malloc(cap + 1);
    while (buf) {
        n += fread(buf + n, 1, cap - n, f);
        if (n < cap)
            break;
        char *grown = realloc(buf, 2 * cap + 1);
        if (!grown) {
            free(buf);
            buf = NULL;
            break;
        }
        buf = grown;
        cap *= 2;
    }
    const bool bad = ferror(f);
    if (path)
        fclose(f);
    if (!buf || bad) {
        tell("%s: cannot read '%s': %s\n", name, shown(path ? path : "stdin").text,
             buf ? "read error" : "out of memory");
        free(buf);
        return NULL;
    }
    buf[n] = '\0';
    *len = n;
    return buf;
}

/* Physical memory, to refuse up front an N this machine cannot hold (SPEC §1). */
static double physical_bytes(void)
{
    const long pages = sysconf(_SC_PHYS_PAGES), size = sysconf(_SC_PAGESIZE);
    return pages > 0 && size > 0 ? (double)pages * (double)size : 0;
}

/* The whole input: read here, or by rank 0 and shared with every rank (an MPI variant, whose
 * stdin is rank 0's). NULL, on every rank, where it could not be read (rank 0 said why). */
static char *read_input(const char *name, const char *path, size_t *len)
{
    const sim_ranks *ranks = sim_variant_def.ranks;
    if (!ranks)
        return read_all(name, path, len);
    char *text = ranks->rank() == 0 ? read_all(name, path, len) : NULL;
    return ranks->share_input(text, len);
}

/* Read (or generate) the scene into w. Returns an exit status. */
static int load_scene(const char *name, const sim_options *o, sim_header *h, sim_world *w)
{
    size_t len;
    char *text = read_input(name, o->input, &len);
    if (!text)
        return SIM_EXIT_USAGE;
    sim_lexer lx;
    sim_error err;
    sim_lexer_init(&lx, text, len);
    if (sim_parse_header(&lx, h, &err)) {
        free(text);
        tell("%s: input: line %ld: %s\n", name, err.line, err.what);
        return SIM_EXIT_USAGE;
    }
    const double need = (double)h->n * (double)sim_bytes_per_particle(), have = physical_bytes();
    if (have > 0 && need > have) {
        free(text);
        tell("%s: input: line 1: N=%ld needs about %.1f GiB, more than this machine's %.1f GiB\n",
             name, (long)h->n, need / (1 << 30), have / (1 << 30));
        return SIM_EXIT_USAGE;
    }
    /* Print mode writes N lines for each of the S + 1 states: past 2^63 bytes (the largest
     * file) the output cannot be kept anywhere. */
    const double lines = (double)h->n * ((double)h->steps + 1);
    if (h->mode == SIM_MODE_PRINT && lines * SIM_PRINT_LINE_MIN > (double)INT64_MAX) {
        free(text);
        tell("%s: input: line 1: print mode with N=%ld and S=%lld writes at least %.3g bytes, "
             "more than a file can hold (2^63)\n", name, (long)h->n, (long long)h->steps,
             lines * SIM_PRINT_LINE_MIN);
        return SIM_EXIT_USAGE;
    }
    unsigned char *listed = calloc((size_t)h->n + 1, 1);
    if (!listed || sim_world_alloc(w, h)) {
        free(text);
        free(listed);
        fprintf(stderr, "%s: out of memory for N=%ld particles\n", name, (long)h->n);
        return SIM_EXIT_RUNTIME;
    }
    const int rc = sim_parse_particles(&lx, h, w, listed, &err);
    free(text);
    if (rc) {
        free(listed);
        sim_world_free(w);
        tell("%s: input: line %ld: %s\n", name, err.line, err.what);
        return SIM_EXIT_USAGE;
    }
    sim_generate(w, h, listed, o->seed);
    free(listed);
    return SIM_EXIT_OK;
}

/* A failure of this process alone in the middle of the steps, its message printed: with
 * several ranks the others would wait for it in the next exchange, so every rank ends now
 * (the run's status is then the launcher's, nonzero). Alone, returns the status. */
static int failed_alone(int status)
{
    const sim_ranks *ranks = sim_variant_def.ranks;
    if (ranks && ranks->size() > 1) {
        fflush(stderr);
        ranks->abort(status);
    }
    return status;
}

/* Run the steps, writing states in print mode, then the final block (rank 0 of an MPI
 * variant writes; the others step alike and write nothing). Returns an exit status. */
static int simulate(const char *name, const sim_options *o, const sim_header *h, sim_world *w,
                    int threads, sim_report *rep)
{
    const bool writes = !quiet;
    sim_stepper *s = sim_stepper_create(w, &sim_variant_def, threads);
    if (!s) {
        fprintf(stderr, "%s: out of memory for N=%ld particles\n", name, (long)h->n);
        return failed_alone(SIM_EXIT_RUNTIME);
    }
    int rc = SIM_EXIT_OK;
    if (o->timing) {
        rep->writers = sim_stepper_writers(s);
        rep->work = calloc((size_t)rep->writers, sizeof *rep->work);
        if (!rep->work)
            rep->writers = 0; /* the line lists no writer */
    }
    /* Without particles nothing moves and nothing is printed: any S ends at once. */
    const int64_t steps = h->n > 0 ? h->steps : 0;
    for (int64_t step = 0; step < steps && rc == SIM_EXIT_OK; step++) {
        if (h->mode == SIM_MODE_PRINT && writes) {
            const double t0 = omp_get_wtime();
            if (sim_write_state(stdout, w, step, o->precise))
                rc = SIM_EXIT_RUNTIME;
            rep->output_s += omp_get_wtime() - t0;
        }
        const double t0 = omp_get_wtime();
        if (rc == SIM_EXIT_OK && sim_step(s, w, &rep->stats)) {
            fprintf(stderr, "%s: out of memory in step %lld\n", name,
                    (long long)step);
            rc = SIM_EXIT_RUNTIME;
        }
        rep->sim_s += omp_get_wtime() - t0;
    }
    const bool stopped = rc != SIM_EXIT_OK; /* a write or a step failed */
    if (stopped && ferror(stdout))
        fprintf(stderr, "%s: cannot write the output: %s\n", name, strerror(errno));
    if (stopped)
        failed_alone(rc);
    for (int k = 0; k < rep->writers; k++)
        rep->work[k] = sim_stepper_work(s, k);
    sim_stepper_destroy(s);
    if (!stopped && writes) {
        const double t0 = omp_get_wtime();
        if (sim_write_final(stdout, w, h->steps, o->precise) || fflush(stdout))
            rc = SIM_EXIT_RUNTIME;
        rep->output_s += omp_get_wtime() - t0;
    }
    if (!stopped && ferror(stdout)) {
        fprintf(stderr, "%s: cannot write the output: %s\n", name, strerror(errno));
        rc = SIM_EXIT_RUNTIME;
    }
    /* The next call every rank makes together is the agreement on the status (main). */
    return rc;
}

/* "f64", or the real type and/or pair formula this binary was built with, e.g. "f32". */
static void build_name(char *buf, size_t len)
{
    const bool real = strcmp(SIM_REAL_NAME, "f64") != 0;
    const bool formula = strcmp(SIM_FORMULA_NAME, "spec") != 0;
    snprintf(buf, len, "%s%s%s", real || !formula ? SIM_REAL_NAME : "",
             real && formula ? "-" : "", formula ? SIM_FORMULA_NAME : "");
}

/* ", \"KEY\": [v0, v1, ...]" of one field of every writer's work. */
static void print_work(const sim_report *r, const char *key, int field)
{
    fprintf(stderr, ", \"%s\": [", key);
    for (int k = 0; k < r->writers; k++) {
        const sim_thread_work *t = &r->work[k];
        if (k)
            fputs(", ", stderr);
        if (field == 0)
            fprintf(stderr, "%.6f", t->busy_s);
        else
            fprintf(stderr, "%llu", (unsigned long long)(field == 1 ? t->pairs : t->chunks));
    }
    fputc(']', stderr);
}

/* With several ranks (an MPI variant), every rank's figures on rank 0: the pair tests added up,
 * and the writers' work listed rank after rank (each rank's padded to the largest count with
 * zeros); the rest stays rank 0's (every rank resolves the same candidates). Every rank calls
 * it: the gathers are collective. */
static void gather_report(const char *name, const sim_ranks *ranks, sim_report *r)
{
    const int size = ranks->size();
    const bool root = ranks->rank() == 0;
    const int writers = ranks->largest(r->writers);
    sim_thread_work *mine = calloc((size_t)writers + 1, sizeof *mine);
    sim_thread_work *work = root ? calloc((size_t)size * (size_t)writers + 1, sizeof *work) : NULL;
    sim_stats *stats = root ? calloc((size_t)size, sizeof *stats) : NULL;
    if (!mine || (root && (!work || !stats))) {
        fprintf(stderr, "%s: out of memory for --timing\n", name);
        failed_alone(SIM_EXIT_RUNTIME);
        free(mine), free(work), free(stats);
        return;
    }
    if (r->writers)
        memcpy(mine, r->work, (size_t)r->writers * sizeof *mine);
    ranks->gather(mine, (size_t)writers * sizeof *mine, work);
    ranks->gather(&r->stats, sizeof r->stats, stats);
    free(mine);
    if (!root)
        return;
    r->stats.pair_tests = 0;
    for (int k = 0; k < size; k++)
        r->stats.pair_tests += stats[k].pair_tests;
    free(stats);
    free(r->work);
    r->work = work;
    r->writers = size * writers;
}

/* --timing's line on stderr (rank 0 of an MPI variant writes it, after gather_report; the
 * variant adds its own fields last). */
static void print_timing(const sim_header *h, int threads, const sim_report *r)
{
    const sim_ranks *ranks = sim_variant_def.ranks;
    if (quiet) {
        ranks->timing(NULL);
        return;
    }
    char build[32];
    build_name(build, sizeof build);
    fprintf(stderr,
            "{\"variant\": \"%s\", \"build\": \"%s\", \"real\": \"%s\", \"formula\": \"%s\", "
            "\"threads\": %d, \"n\": %ld, \"steps\": %lld, \"input_s\": %.6f, \"sim_s\": %.6f, "
            "\"broad_s\": %.6f, \"walls_s\": %.6f, \"sort_s\": %.6f, \"resolve_s\": %.6f, "
            "\"motion_s\": %.6f, \"output_s\": %.6f, \"pair_tests\": %llu, \"candidates\": %llu, "
            "\"pair_collisions\": %llu, \"wall_collisions\": %llu",
            sim_variant_def.name, build, SIM_REAL_NAME, SIM_FORMULA_NAME, threads, (long)h->n,
            (long long)h->steps, r->input_s, r->sim_s, r->stats.broad_s, r->stats.walls_s,
            r->stats.sort_s, r->stats.resolve_s, r->stats.motion_s, r->output_s,
            (unsigned long long)r->stats.pair_tests, (unsigned long long)r->stats.candidates,
            (unsigned long long)r->stats.pair_collisions,
            (unsigned long long)r->stats.wall_collisions);
    /* Per candidate writer (the threads; T*T for p3): busy seconds in the pair finder, pair
     * tests and chunks dealt, in thread order. */
    print_work(r, "threads_busy_s", 0);
    print_work(r, "threads_pairs", 1);
    print_work(r, "threads_chunks", 2);
    if (ranks)
        ranks->timing(stderr);
    fputs("}\n", stderr);
}

/* The run: main's work between the start and the stop of an MPI variant's ranks. */
static int run(int argc, char **argv)
{
    const char *name = sim_variant_def.name;
    sim_options o;
    int rc = parse_options(name, argc, argv, &o);
    if (rc != SIM_EXIT_OK)
        return rc;
    if (o.help) {
        if (!quiet)
            printf(usage_text, argv[0], argv[0], argv[0]);
        return SIM_EXIT_OK;
    }
    if (o.describe) {
        if (!quiet && (sim_describe(stdout, &sim_variant_def) || fflush(stdout))) {
            fprintf(stderr, "%s: cannot write the output: %s\n", name, strerror(errno));
            return SIM_EXIT_RUNTIME;
        }
        return SIM_EXIT_OK;
    }
    static char stdout_buffer[SIM_STDOUT_BUFFER];
    setvbuf(stdout, stdout_buffer, _IOFBF, sizeof stdout_buffer);

    const int threads = !sim_variant_def.parallel ? 1 : o.threads > 0 ? o.threads
                                                                      : omp_get_max_threads();
    omp_set_num_threads(threads);

    const sim_ranks *ranks = sim_variant_def.ranks;
    if (o.replay && ranks && ranks->size() > 1) {
        tell("%s: usage: --replay runs as one process, not %d MPI ranks (try --help)\n", name,
             ranks->size());
        return SIM_EXIT_USAGE;
    }
    if (o.replay) {
        size_t len;
        char *text = read_all(name, o.input, &len);
        if (!text)
            return SIM_EXIT_USAGE;
        rc = sim_replay(stdout, name, text, len, threads);
        free(text);
        if (rc == SIM_EXIT_OK && fflush(stdout)) {
            fprintf(stderr, "%s: cannot write the output: %s\n", name, strerror(errno));
            rc = SIM_EXIT_RUNTIME;
        }
        return rc;
    }

    sim_report rep = {0};
    sim_header h;
    sim_world w;
    const double t0 = omp_get_wtime();
    rc = load_scene(name, &o, &h, &w);
    if (ranks) {
        /* Every rank parsed the same text; only memory, or a machine with less of it, can
         * make one fail where rank 0 did not. */
        const int all = ranks->largest(rc);
        if (all != SIM_EXIT_OK && rc == SIM_EXIT_OK) {
            tell("%s: another rank could not load the scene (status %d)\n", name, all);
            sim_world_free(&w);
        }
        rc = all;
    }
    if (rc != SIM_EXIT_OK)
        return rc;
    rep.input_s = omp_get_wtime() - t0;
    rc = simulate(name, &o, &h, &w, threads, &rep);
    sim_world_free(&w);
    if (ranks)
        rc = ranks->largest(rc);
    if (rc == SIM_EXIT_OK && o.timing) {
        if (ranks)
            gather_report(name, ranks, &rep);
        print_timing(&h, threads, &rep);
    }
    free(rep.work);
    return rc;
}

/* Whether the command line asks only what the binary is (--describe, --help): answered without
 * starting ranks, which it does not need (and an MPI start can fail beside another process's).
 * A command line that does not parse is run() as any other, which says why. */
static bool about_itself(int argc, char **argv)
{
    sim_options o;
    quiet = true;
    const bool self = parse_options(sim_variant_def.name, argc, argv, &o) == SIM_EXIT_OK &&
                      (o.help || o.describe);
    quiet = false;
    return self;
}

int main(int argc, char **argv)
{
    const sim_ranks *ranks = sim_variant_def.ranks;
    if (!ranks || (!ranks->launched() && about_itself(argc, argv)))
        return run(argc, argv);
    if (ranks->start(&argc, &argv))
        return SIM_EXIT_RUNTIME;
    quiet = ranks->rank() != 0;
    const int rc = run(argc, argv);
    ranks->stop();
    return rc;
}
