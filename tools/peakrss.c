/*
 * peakrss: run a command as the child of this small process and report its peak resident
 * memory.
 *
 *   peakrss FD COMMAND [ARG...]
 *
 * Runs COMMAND, waits for it with wait4 and writes one line to the open file descriptor FD:
 * its ru_maxrss (KiB on Linux: the largest resident set of COMMAND and of every descendant it
 * waited for, such as a shell's commands; the largest of them, not their sum). Then ends as
 * COMMAND did: with its exit status, or killed by the same signal. FD is not passed on to
 * COMMAND. Exit 127 (as a shell's) where COMMAND cannot be run, 2 on a usage error.
 *
 * Why a process of its own: the kernel starts a child's ru_maxrss at the high-water mark of
 * the memory it was forked with, kept when it calls exec. A command the harness (a Python
 * process of 15 MiB or more) started itself would report at least the harness's resident set;
 * forked from this process (about 1 MiB) it reports its own, as /usr/bin/time does.
 */
#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#define EXIT_USAGE 2
#define EXIT_CANNOT_RUN 127
#define SHELL_SIGNAL_BASE 128

/* End as the child ended: killed by its signal (no core file of our own), else its status. */
static int end_as(int status)
{
    if (WIFSIGNALED(status)) {
        int sig = WTERMSIG(status);
        struct rlimit none = {0, 0};
        sigset_t set;
        setrlimit(RLIMIT_CORE, &none);
        signal(sig, SIG_DFL);
        sigemptyset(&set);
        sigaddset(&set, sig);
        sigprocmask(SIG_UNBLOCK, &set, NULL);
        raise(sig);
        return SHELL_SIGNAL_BASE + sig; /* a signal that does not end a process */
    }
    return WIFEXITED(status) ? WEXITSTATUS(status) : EXIT_FAILURE;
}

int main(int argc, char **argv)
{
    char *end = NULL;
    long fd = argc > 2 ? strtol(argv[1], &end, 10) : -1;
    if (argc < 3 || end == argv[1] || *end != '\0' || fd < 0 || fd > 1 << 20) {
        fprintf(stderr, "usage: peakrss FD COMMAND [ARG...]\n");
        return EXIT_USAGE;
    }
    FILE *report = fdopen((int)fd, "w");
    if (report == NULL || fcntl((int)fd, F_SETFD, FD_CLOEXEC) != 0) {
        fprintf(stderr, "peakrss: file descriptor %ld: %s\n", fd, strerror(errno));
        return EXIT_USAGE;
    }
    pid_t child = fork();
    if (child < 0) {
        fprintf(stderr, "peakrss: cannot fork: %s\n", strerror(errno));
        return EXIT_CANNOT_RUN;
    }
    if (child == 0) {
        execvp(argv[2], argv + 2);
        fprintf(stderr, "cannot run %s: %s\n", argv[2], strerror(errno));
        _exit(EXIT_CANNOT_RUN);
    }
    int status = 0;
    struct rusage usage;
    while (wait4(child, &status, 0, &usage) < 0) {
        if (errno != EINTR) {
            fprintf(stderr, "peakrss: wait4: %s\n", strerror(errno));
            return EXIT_FAILURE;
        }
    }
    fprintf(report, "%ld\n", usage.ru_maxrss);
    fclose(report);
    return end_as(status);
}
