/*
 * slow_wrapper: a binary that is the real variant made a known fraction slower, for measuring
 * what `compare --measure` detects. Installed as DIR/NAME, it runs REAL_DIR/NAME with the same
 * arguments (stdin, stdout and stderr passed through), then spins for FRACTION of the wall
 * time the real run took, and exits with its status.
 *
 *   cc -O2 -o DIR/seq scripts/slow_wrapper.c -DREAL_DIR='"/path/to/build"' -DFRACTION=0.05
 */
#define _POSIX_C_SOURCE 200809L
#include <libgen.h>
#include <stdio.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

static double now_s(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

int main(int argc, char **argv)
{
    (void)argc;
    char self[4096], real[8192];
    snprintf(self, sizeof self, "%s", argv[0]);
    snprintf(real, sizeof real, "%s/%s", REAL_DIR, basename(self));
    const double start = now_s();
    const pid_t child = fork();
    if (child < 0) {
        perror("slow_wrapper: fork");
        return 1;
    }
    if (child == 0) {
        argv[0] = real;
        execv(real, argv);
        perror("slow_wrapper: exec");
        _exit(127);
    }
    int status = 0;
    waitpid(child, &status, 0);
    const double until = now_s() + FRACTION * (now_s() - start);
    volatile unsigned long spin = 0;
    while (now_s() < until)
        spin++;
    return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}
