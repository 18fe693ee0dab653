/*
 * mpi_ranks.c: the mpi variant's processes (sim_ranks, sim.h): MPI started and stopped, rank
 * 0's input broadcast, statuses agreed, a lone failure turned into the end of every rank, and
 * --timing's figures of every rank gathered on rank 0 (seconds in MPI calls, bytes moved per
 * step, peak resident memory).
 */
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>

#include "ranks.h"

/* The most bytes one MPI call moves here: its counts are ints. */
#define MPI_CHUNK_MAX (1 << 30)

static int rank_of = 0, size_of = 1;

/* What this rank's MPI calls cost, for --timing. */
static struct {
    double seconds;       /* in every MPI call (the --timing gathers excepted) */
    uint64_t step_bytes;  /* payload sent and received in the steps' exchanges */
    uint64_t steps;       /* steps exchanged */
} meter;

int mpi_rank(void)
{
    return rank_of;
}

int mpi_size(void)
{
    return size_of;
}

void mpi_meter_call(double t0, uint64_t sent, uint64_t received, int in_step)
{
    meter.seconds += MPI_Wtime() - t0;
    if (in_step)
        meter.step_bytes += sent + received;
}

void mpi_meter_step(void)
{
    meter.steps++;
}

/* Whether a launcher (mpirun, mpiexec, srun) started this process: each sets its rank in the
 * environment. */
static bool launched(void)
{
    static const char *const marks[] = {"OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_RANK", "PMI_FD",
                                        "SLURM_PROCID"};
    for (size_t k = 0; k < sizeof marks / sizeof marks[0]; k++)
        if (getenv(marks[k]))
            return 1;
    return 0;
}

static int start(int *argc, char ***argv)
{
    /* Started without a launcher, the process is a world of one (MPI's singleton): there is no
     * peer to reach. Unless the environment says otherwise, Open MPI is asked not to fork its
     * runtime daemon for it and to load only the transport to itself, not to probe the network
     * (UCX): a start took 0.36 s here with both, 0.04 s without. Other MPIs ignore these. */
    if (!launched()) {
        setenv("OMPI_MCA_ess_singleton_isolated", "1", 0);
        setenv("OMPI_MCA_pml", "ob1", 0);
        setenv("OMPI_MCA_btl", "self", 0);
    }
    int provided = 0;
    if (MPI_Init_thread(argc, argv, MPI_THREAD_FUNNELED, &provided) != MPI_SUCCESS) {
        fprintf(stderr, "mpi: MPI_Init_thread failed\n");
        return -1;
    }
    MPI_Comm_rank(MPI_COMM_WORLD, &rank_of);
    MPI_Comm_size(MPI_COMM_WORLD, &size_of);
    if (provided < MPI_THREAD_FUNNELED) {
        if (rank_of == 0)
            fprintf(stderr, "mpi: this MPI library gives no thread support (MPI_THREAD_FUNNELED "
                            "is needed beside the OpenMP threads)\n");
        MPI_Finalize();
        return -1;
    }
    return 0;
}

static void stop(void)
{
    MPI_Finalize();
}

static void end_all(int status)
{
    MPI_Abort(MPI_COMM_WORLD, status);
    exit(status); /* MPI_Abort does not return; in case a library's does */
}

/* buf[0, n) from rank 0 to every rank, in calls of at most MPI_CHUNK_MAX bytes. */
static void broadcast(void *buf, uint64_t n)
{
    const double t0 = MPI_Wtime();
    for (uint64_t at = 0; at < n; at += MPI_CHUNK_MAX) {
        const uint64_t part = n - at < MPI_CHUNK_MAX ? n - at : MPI_CHUNK_MAX;
        MPI_Bcast((char *)buf + at, (int)part, MPI_BYTE, 0, MPI_COMM_WORLD);
    }
    mpi_meter_call(t0, rank_of == 0 ? n * (uint64_t)(size_of - 1) : 0, rank_of == 0 ? 0 : n, 0);
}

static char *share_input(char *text, size_t *len)
{
    uint64_t n = rank_of == 0 ? (text ? (uint64_t)*len : UINT64_MAX) : 0;
    broadcast(&n, sizeof n);
    if (n == UINT64_MAX)
        return NULL; /* rank 0 could not read, and said why */
    if (rank_of != 0) {
        text = n < SIZE_MAX ? malloc((size_t)n + 1) : NULL;
        if (!text) {
            fprintf(stderr, "mpi: rank %d: out of memory for the input (%llu bytes)\n", rank_of,
                    (unsigned long long)n);
            end_all(1);
        }
        text[n] = '\0';
    }
    broadcast(text, n);
    *len = (size_t)n;
    return text;
}

static int largest(int value)
{
    const double t0 = MPI_Wtime();
    int all = value;
    MPI_Allreduce(&value, &all, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
    mpi_meter_call(t0, 0, 0, 0);
    return all;
}

static void gather(const void *mine, size_t bytes, void *all)
{
    if (bytes > INT_MAX) {
        fprintf(stderr, "mpi: rank %d: a gather of %zu bytes, more than one MPI call moves\n",
                rank_of, bytes);
        end_all(1);
    }
    MPI_Gather(mine, (int)bytes, MPI_BYTE, all, (int)bytes, MPI_BYTE, 0, MPI_COMM_WORLD);
}

/* One rank's figures for --timing. */
enum { FIG_MPI_S, FIG_STEP_BYTES, FIG_RSS_MIB, FIGS };

static void timing(FILE *out)
{
    struct rusage use;
    double mine[FIGS] = {meter.seconds, meter.steps ? (double)meter.step_bytes / meter.steps : 0,
                         getrusage(RUSAGE_SELF, &use) == 0 ? use.ru_maxrss / 1024.0 : 0};
    double *all = rank_of == 0 ? calloc((size_t)size_of, sizeof mine) : NULL;
    if (rank_of == 0 && !all) {
        fprintf(stderr, "mpi: out of memory for --timing\n");
        end_all(1);
    }
    gather(mine, sizeof mine, all);
    if (!out)
        return;
    double max[FIGS] = {0}, sum[FIGS] = {0};
    for (int r = 0; r < size_of; r++)
        for (int f = 0; f < FIGS; f++) {
            const double v = all[(size_t)r * FIGS + f];
            max[f] = v > max[f] ? v : max[f];
            sum[f] += v;
        }
    free(all);
    fprintf(out, ", \"ranks\": %d, \"mpi_s\": %.6f, \"mpi_s_mean\": %.6f, \"mpi_bytes_step\": %.0f, "
                 "\"mpi_bytes_step_mean\": %.0f, \"rss_mib_max\": %.1f, \"rss_mib_sum\": %.1f",
            size_of, max[FIG_MPI_S], sum[FIG_MPI_S] / size_of, max[FIG_STEP_BYTES],
            sum[FIG_STEP_BYTES] / size_of, max[FIG_RSS_MIB], sum[FIG_RSS_MIB]);
}

const sim_ranks mpi_ranks = {
    .launched = launched,
    .start = start,
    .stop = stop,
    .rank = mpi_rank,
    .size = mpi_size,
    .share_input = share_input,
    .largest = largest,
    .abort = end_all,
    .gather = gather,
    .timing = timing,
};

#if defined(__SANITIZE_ADDRESS__)
/* The ASan build (make asan). Open MPI's libraries keep blocks to the end of the process that
 * no pointer reaches any more (from MPI_Init, its runtime and plugins), and they are built
 * without frame pointers, so LeakSanitizer's default (fast) unwinder cannot tell their blocks
 * from ours: every run would fail on them. So leak detection is off by default in this build
 * (the sanitizers' other checks stay on), and on where a run asks for it with the exact
 * unwinder, ASAN_OPTIONS=detect_leaks=1:fast_unwind_on_malloc=0 (tests/c/mpi_scenes.sh does,
 * on a few runs: a start then takes about a second): then only the leaks whose stack passes
 * through Open MPI's libraries are suppressed, and the core's and this variant's are reported. */
const char *__asan_default_options(void);
const char *__asan_default_options(void)
{
    return "detect_leaks=0";
}

const char *__lsan_default_suppressions(void);
const char *__lsan_default_suppressions(void)
{
    return "leak:libmpi.so\nleak:libopen-pal.so\nleak:libopen-rte.so\nleak:libhwloc.so\n"
           "leak:libevent\nleak:libpmix.so\nleak:mca_\n";
}
#endif
