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
    sim_cand *all;       /* the step's candidates of every rank, gathered */
    size_t cap;          /* candidates `all` holds */
    int *counts, *displs; /* per rank: its candidates and where they go in `all` */
    uint64_t *shared;    /* per rank: candidates kept and left out */
    MPI_Datatype cand;   /* one sim_cand, as bytes (every rank runs this binary) */
} mpi_scratch;

static void scratch_destroy(void *p)
{
    mpi_scratch *m = p;
    if (!m)
        return;
    grid_scratch_destroy(m->grid);
    free(m->all), free(m->counts), free(m->displs), free(m->shared);
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

/* Every rank's candidates into the sink's buffer 0 on every rank (the others emptied): the
 * counts all-gathered, then the candidates, each rank's block straight into its place. */
static void exchange(mpi_scratch *m, sim_pair_sink *sink)
{
    const int rank = mpi_rank(), size = mpi_size();
    uint64_t mine[2] = {0, 0}; /* kept, left out */
    for (int k = 0; k < sink->count; k++) {
        mine[1] += drop_walled(&sink->bufs[k], sink->wall_t);
        mine[0] += sink->bufs[k].len;
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
    if (total > m->cap) {
        free(m->all);
        m->cap = total + total / 4;
        m->all = malloc(m->cap * sizeof *m->all);
        if (!m->all)
            fail("out of memory for the step's candidates");
    }
    sim_cand *at = m->all + m->displs[rank];
    for (int k = 0; k < sink->count; k++) {
        if (sink->bufs[k].len)
            memcpy(at, sink->bufs[k].items, sink->bufs[k].len * sizeof *at);
        at += sink->bufs[k].len;
        sink->bufs[k].len = 0;
    }
    t0 = MPI_Wtime();
    MPI_Allgatherv(MPI_IN_PLACE, 0, MPI_DATATYPE_NULL, m->all, m->counts, m->displs, m->cand,
                   MPI_COMM_WORLD);
    mpi_meter_call(t0, mine[0] * sizeof(sim_cand) * (uint64_t)(size - 1),
                   (total - mine[0]) * sizeof(sim_cand), 1);
    mpi_meter_step();
    /* The gathered list becomes buffer 0, whose storage the next exchange gathers into. */
    sim_cand_buf *b = &sink->bufs[0];
    sim_cand *items = b->items;
    const size_t cap = b->cap;
    b->items = m->all, b->cap = m->cap, b->len = total;
    b->dropped += dropped;
    m->all = items, m->cap = cap;
}

static void find_pairs(const sim_world *w, sim_pair_sink *sink)
{
    mpi_scratch *m = sink->scratch;
    sim_pair_sink part = *sink;
    part.scratch = m->grid;
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
