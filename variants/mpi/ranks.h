/*
 * ranks.h: what the mpi variant's files share (and nothing else includes): the ranks' hooks
 * that the core calls (sim_ranks, mpi_ranks.c) and the meter of the MPI calls that --timing
 * reports. Named ranks.h, not mpi.h, so that no include of this directory can take the place of
 * the MPI library's <mpi.h>.
 */
#ifndef MPI_RANKS_H
#define MPI_RANKS_H

#include <stdint.h>

#include <mpi.h>

#include "../core/sim.h"

/* The ranks' hooks (sim_variant's `ranks`): MPI started with MPI_THREAD_FUNNELED (only the
 * thread that calls main calls MPI, outside the OpenMP regions), errors fatal (a failed call
 * ends every rank rather than leaving one waiting). */
extern const sim_ranks mpi_ranks;

/* This process's rank in MPI_COMM_WORLD and the number of ranks (valid once started). */
int mpi_rank(void);
int mpi_size(void);

/* The MPI calls' meter, for --timing: `seconds` spent in an MPI call that started at t0 (its
 * MPI_Wtime), its payload sent and received by this rank (what the call moves whatever its
 * algorithm: a rank's own block to each of the others, theirs to it), and whether it is a
 * step's exchange (steps are counted by mpi_meter_step). */
void mpi_meter_call(double t0, uint64_t sent, uint64_t received, int in_step);
void mpi_meter_step(void);

#endif /* MPI_RANKS_H */
