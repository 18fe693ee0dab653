/*
 * mpi: grid's finder on MPI ranks (hybrid MPI + OpenMP). Every rank holds the whole world and
 * runs the same steps. In each step, each of the R ranks runs grid's space-time grid
 * (variants/grid/, linked as it is) on every R-th time slice of the step, with its T OpenMP
 * threads; a candidate is pushed from exactly one slice, so the ranks' candidates together are
 * grid's, each once. The candidates are then exchanged (MPI_Allgatherv), and every rank's core
 * sorts them by the total SPEC key and resolves them alike: the same state everywhere, and
 * seq's output, which rank 0 writes. Before the exchange each rank leaves out the pairs a wall
 * comes first for (the sort would drop them): most of them, fewer bytes to move.
 *
 * Why slices, replicated state and an all-gather, and what it costs: docs/mpi.md. The ranks'
 * start, input, statuses and --timing figures: mpi/mpi_ranks.c.
 */
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <mpi.h>

#include "grid/grid.h"
#include "mpi/ranks.h"

/* The finder's per-run memory: grid's own, and the exchange's. */
typedef struct mpi_scratch {
    grid_scratch *grid;
    /* The buffers grid's finder writes this rank's candidates into, one a writer as the core's
     * (`count` of them): the core's own buffer 0 is where every rank's are gathered, so that a
     * rank holds the step's candidates once, and its own share once more. */
    sim_cand_buf *local;
    int count;
    int *counts, *displs; /* per rank: its candidates and where they go in the gathered list */
    uint64_t *shared;    /* per rank: candidates kept and left out */
    MPI_Datatype cand;   /* one sim_cand, as bytes (every rank runs this binary) */
} mpi_scratch;

static void scratch_destroy(void *p)
{
    mpi_scratch *m = p;
    if (!m)
        return;
    grid_scratch_destroy(m->grid);
    for (int k = 0; k < m->count && m->local; k++)
        free(m->local[k].items);
    free(m->local), free(m->counts), free(m->displs), free(m->shared);
    if (m->cand != MPI_DATATYPE_NULL)
        MPI_Type_free(&m->cand);
    free(m);
}

static void *scratch_create(const sim_world *w, int threads)
{
    mpi_scratch *m = calloc(1, sizeof *m);
    if (!m)
        return NULL;
    m->cand = MPI_DATATYPE_NULL;
    const size_t ranks = (size_t)mpi_size();
    m->grid = grid_scratch_create(w, threads);
    m->counts = malloc(ranks * sizeof *m->counts);
    m->displs = malloc(ranks * sizeof *m->displs);
    m->shared = malloc(2 * ranks * sizeof *m->shared);
    if (!m->grid || !m->counts || !m->displs || !m->shared) {
        scratch_destroy(m);
        return NULL;
    }
    m->grid->slice_part = mpi_rank();
    m->grid->slice_parts = mpi_size();
    MPI_Type_contiguous((int)sizeof(sim_cand), MPI_BYTE, &m->cand);
    MPI_Type_commit(&m->cand);
    return m;
}

/* Leave out of buf the pairs a wall of one of their particles comes first for, as the core's
 * sort would (sim_pair_sink's wall_t); returns how many. */
static uint64_t drop_walled(sim_cand_buf *buf, const sim_real *restrict wall_t)
{
    sim_cand *restrict c = buf->items;
    size_t out = 0;
    for (size_t k = 0; k < buf->len; k++) {
        const sim_cand e = c[k];
        c[out] = e;
        out += !((wall_t[e.i] < e.t) | (wall_t[e.j] < e.t));
    }
    const uint64_t dropped = buf->len - out;
    buf->len = out;
    return dropped;
}

/* This rank's failure in the exchange, which the others cannot see: every rank ends. */
static void fail(const char *what)
{
    fprintf(stderr, "mpi: rank %d: %s\n", mpi_rank(), what);
    fflush(stderr);
    mpi_ranks.abort(1);
}

/* Every rank's candidates (m->local on each) into the sink's buffer 0 on every rank: the
 * counts all-gathered, then the candidates, each rank's block into its place in buffer 0
 * first. The writers' figures (--timing) go to the sink's buffers, as grid's would. */
static void exchange(mpi_scratch *m, sim_pair_sink *sink)
{
    const int rank = mpi_rank(), size = mpi_size();
    uint64_t mine[2] = {0, 0}; /* kept, left out */
    for (int k = 0; k < m->count; k++) {
        sim_cand_buf *from = &m->local[k], *to = &sink->bufs[k];
        to->pair_tests += from->pair_tests, to->busy_s += from->busy_s;
        to->chunks += from->chunks, to->failed |= from->failed;
        from->pair_tests = 0, from->busy_s = 0, from->chunks = 0;
        mine[1] += drop_walled(from, sink->wall_t);
        mine[0] += from->len;
    }
    double t0 = MPI_Wtime();
    MPI_Allgather(mine, 2, MPI_UINT64_T, m->shared, 2, MPI_UINT64_T, MPI_COMM_WORLD);
    const uint64_t others = (uint64_t)(size - 1) * sizeof mine;
    mpi_meter_call(t0, others, others, 1);
    uint64_t total = 0, dropped = 0;
    for (int r = 0; r < size; r++) {
        if (m->shared[2 * r] > INT_MAX || total + m->shared[2 * r] > INT_MAX)
            fail("more candidates in a step than one MPI call gathers (2^31 - 1)");
        m->displs[r] = (int)total;
        m->counts[r] = (int)m->shared[2 * r];
        total += m->shared[2 * r];
        dropped += m->shared[2 * r + 1];
    }
    sim_cand_buf *all = &sink->bufs[0]; /* empty: the core has sorted the last step's */
    if (total > all->cap) {
        const size_t cap = total + total / 4;
        sim_cand *items = realloc(all->items, cap * sizeof *items);
        if (!items)
            fail("out of memory for the step's candidates");
        all->items = items, all->cap = cap;
    }
    sim_cand *at = all->items + m->displs[rank];
    for (int k = 0; k < m->count; k++) {
        if (m->local[k].len)
            memcpy(at, m->local[k].items, m->local[k].len * sizeof *at);
        at += m->local[k].len;
        m->local[k].len = 0;
    }
    t0 = MPI_Wtime();
    MPI_Allgatherv(MPI_IN_PLACE, 0, MPI_DATATYPE_NULL, all->items, m->counts, m->displs,
                   m->cand, MPI_COMM_WORLD);
    mpi_meter_call(t0, mine[0] * sizeof(sim_cand) * (uint64_t)(size - 1),
                   (total - mine[0]) * sizeof(sim_cand), 1);
    mpi_meter_step();
    all->len = total;
    all->dropped += dropped;
}

static void find_pairs(const sim_world *w, sim_pair_sink *sink)
{
    mpi_scratch *m = sink->scratch;
    if (!m->local) {
        /* sizeof(sim_cand_buf) is a multiple of its 64-byte alignment, as aligned_alloc needs. */
        m->local = aligned_alloc(_Alignof(sim_cand_buf), (size_t)sink->count * sizeof *m->local);
        if (!m->local)
            fail("out of memory for the finder's buffers");
        memset(m->local, 0, (size_t)sink->count * sizeof *m->local);
        m->count = sink->count;
    }
    sim_pair_sink part = *sink;
    part.scratch = m->grid;
    part.bufs = m->local;
    grid_find_pairs(w, &part); /* this rank's share of the slices */
    exchange(m, sink);
}

const sim_variant sim_variant_def = {
    .name = "mpi",
    .summary = "grid's space-time grid on MPI ranks, each on every R-th time slice of a step "
               "with its threads; the candidates all-gathered and resolved alike on every rank",
    .exact = true,
    .parallel = true,
    .all_pairs = false,
    .repairs = NULL,
    .mpi = true,
    .scratch_create = scratch_create,
    .scratch_destroy = scratch_destroy,
    .find_pairs = find_pairs,
    .ranks = &mpi_ranks,
};
