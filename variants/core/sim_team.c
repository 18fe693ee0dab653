/*
 * sim_team.c: placing the OpenMP team once, before the first step.
 *
 * Why: on a VM a new OpenMP thread is often queued on the CPU of the thread that created it,
 * which is busy, and it waits there until the scheduler's load balancer moves it, a tick or
 * two later. On the development machine (2 vCPUs) the first few parallel regions of a run
 * took 4-12 ms each for that reason instead of microseconds; a 2-thread grid run of the
 * report benchmark takes under 0.2 s in all. Moving each thread once to its own CPU and
 * handing it back the whole mask at once costs 2-3 ms there, and every later region starts in
 * microseconds. Threads stay free to move afterwards (this is not OMP_PROC_BIND: pinning for
 * the whole run measured slower).
 */
#define _GNU_SOURCE /* sched_setaffinity and the CPU_* macros */
#include <omp.h>

#if defined(__linux__)
#include <sched.h>
#endif

#include "sim_core.h"

void sim_team_spread(int threads)
{
#if defined(__linux__)
    if (threads < 2)
        return;
#pragma omp parallel num_threads(threads)
    {
        cpu_set_t all;
        CPU_ZERO(&all);
        if (sched_getaffinity(0, sizeof all, &all) == 0 && CPU_COUNT(&all) > 1) {
            /* Thread t goes to the (t mod count)-th CPU of the mask, then gets the mask back. */
            const int want = omp_get_thread_num() % CPU_COUNT(&all);
            cpu_set_t one;
            CPU_ZERO(&one);
            for (int c = 0, seen = 0; c < CPU_SETSIZE; c++)
                if (CPU_ISSET(c, &all) && seen++ == want) {
                    CPU_SET(c, &one);
                    break;
                }
            /* Failure of either call leaves the thread where the scheduler put it: no harm. */
            if (sched_setaffinity(0, sizeof one, &one) == 0)
                (void)sched_setaffinity(0, sizeof all, &all);
        }
    }
#else
    (void)threads;
#endif
}
