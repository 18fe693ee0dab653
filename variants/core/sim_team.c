/*
 * sim_team.c: placing the OpenMP team once, before the first step.
 *
 * Why: on a VM a new OpenMP thread is often queued on the CPU of the thread that created it,
 * while the creator busy-waits there for it (libgomp spins about 300,000 times before it
 * sleeps), so the new thread starts a scheduler tick or two (4-8 ms) late; and until the load
 * balancer separates them, the two keep meeting on one CPU at later regions. On the
 * development machine (2 vCPUs) a 2-thread run of a 10-particle scene took 7.9 ms (median of
 * 100) against 1.1 ms on one thread; a 2-thread grid run of the report benchmark takes under
 * 0.2 s in all.
 *
 * What: two regions, each moving thread t once to the (t mod count)-th CPU of the process's
 * mask and then handing it back the whole mask (threads stay free to move afterwards: this is
 * not OMP_PROC_BIND, and pinning for the whole run measured slower).
 *  1. A team one thread larger than the CPUs. libgomp, seeing more threads than CPUs, spins
 *     only briefly before it sleeps ("throttled"), so a queued new thread gets the CPU at once.
 *  2. A team of the run's own size: libgomp ends the extra thread and spins normally again
 *     (fast region starts for the rest of the run), and every thread of the team is placed.
 * Measured there (hyperfine, 100 runs of `grid --threads 2` on the 10-particle scene): 7.9 ms
 * median with region 2 alone, 1.4 ms with both; a run in progress holds 2 threads, not 3.
 * Region 1 is skipped where the team already outnumbers the CPUs (the runtime throttles by
 * itself), and on machines of more than SIM_TEAM_OVER_MAX_CPUS CPUs: there a thread per CPU
 * might cost more to start than the stall it avoids (not measured: the development machine has
 * 2 CPUs).
 */
#define _GNU_SOURCE /* sched_setaffinity and the CPU_* macros */
#include <omp.h>

#if defined(__linux__)
#include <sched.h>
#endif

#include "sim_core.h"

/* Most CPUs for which region 1 (a thread per CPU, and one more) is started. */
#define SIM_TEAM_OVER_MAX_CPUS 64

#if defined(__linux__)
/* One region of `team` threads: thread t goes to the (t mod count)-th CPU of `all`, then gets
 * `all` back. Failure of either call leaves the thread where the scheduler put it: no harm. */
static void place_team(int team, const cpu_set_t *all)
{
    const int count = CPU_COUNT(all);
#pragma omp parallel num_threads(team)
    {
        const int want = omp_get_thread_num() % count;
        cpu_set_t one;
        CPU_ZERO(&one);
        for (int c = 0, seen = 0; c < CPU_SETSIZE; c++)
            if (CPU_ISSET(c, all) && seen++ == want) {
                CPU_SET(c, &one);
                break;
            }
        if (sched_setaffinity(0, sizeof one, &one) == 0)
            (void)sched_setaffinity(0, sizeof *all, all);
    }
}
#endif

void sim_team_spread(int threads)
{
#if defined(__linux__)
    cpu_set_t all;
    CPU_ZERO(&all);
    if (threads < 2 || sched_getaffinity(0, sizeof all, &all) != 0)
        return;
    const int cpus = CPU_COUNT(&all);
    if (cpus < 2)
        return;
    if (threads <= cpus && cpus <= SIM_TEAM_OVER_MAX_CPUS)
        place_team(cpus + 1, &all);
    place_team(threads, &all);
#else
    (void)threads;
#endif
}
