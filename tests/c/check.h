/*
 * check.h: the small assertion set and runner the C tests share. Each test file includes it
 * once, lists its tests in `static const test_case tests[]` and ends with
 * `int main(int argc, char **argv) { return run_tests(tests, TEST_COUNT(tests), argc, argv); }`.
 * Output: one line per failed check (file:line and values), then `N passed, M failed`; the exit
 * status is 1 when anything failed. Arguments select tests by substring of their names.
 */
#ifndef CHECK_H
#define CHECK_H

#include <stdarg.h>
#include <stdbool.h>
#include <stdio.h>
#include <string.h>

static int checks_failed; /* in the current test */

static void fail_at(const char *file, int line, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    printf("%s:%d: ", file, line);
    vprintf(fmt, ap);
    printf("\n");
    va_end(ap);
    checks_failed++;
}

#define CHECK(cond)                                                                           \
    do {                                                                                      \
        if (!(cond))                                                                          \
            fail_at(__FILE__, __LINE__, "CHECK(%s) failed", #cond);                           \
    } while (0)

#define CHECK_INT(got, want)                                                                  \
    do {                                                                                      \
        const long long got_ = (long long)(got), want_ = (long long)(want);                  \
        if (got_ != want_)                                                                    \
            fail_at(__FILE__, __LINE__, "%s: got %lld, expected %lld", #got, got_, want_);    \
    } while (0)

#define CHECK_U64(got, want)                                                                  \
    do {                                                                                      \
        const uint64_t got_ = (got), want_ = (want);                                          \
        if (got_ != want_)                                                                    \
            fail_at(__FILE__, __LINE__, "%s: got 0x%016" PRIx64 ", expected 0x%016" PRIx64,   \
                    #got, got_, want_);                                                       \
    } while (0)

/* Exact equality of doubles, sign of zero included. */
#define CHECK_REAL(got, want)                                                                 \
    do {                                                                                      \
        const double got_ = (double)(got), want_ = (double)(want);                            \
        if (!(got_ == want_ && signbit(got_) == signbit(want_)))                              \
            fail_at(__FILE__, __LINE__, "%s: got %.17g (%a), expected %.17g (%a)", #got,      \
                    got_, got_, want_, want_);                                                \
    } while (0)

#define CHECK_NEAR(got, want, tol)                                                            \
    do {                                                                                      \
        const double got_ = (double)(got), want_ = (double)(want), tol_ = (tol);              \
        if (!(fabs(got_ - want_) <= tol_))                                                    \
            fail_at(__FILE__, __LINE__, "%s: got %.17g, expected %.17g within %g", #got,      \
                    got_, want_, tol_);                                                       \
    } while (0)

#define CHECK_STR(got, want)                                                                  \
    do {                                                                                      \
        const char *got_ = (got), *want_ = (want);                                            \
        if (strcmp(got_, want_) != 0)                                                         \
            fail_at(__FILE__, __LINE__, "%s: got \"%s\", expected \"%s\"", #got, got_, want_);\
    } while (0)

#define CHECK_CONTAINS(got, part)                                                             \
    do {                                                                                      \
        const char *got_ = (got), *part_ = (part);                                            \
        if (!strstr(got_, part_))                                                             \
            fail_at(__FILE__, __LINE__, "%s: got \"%s\", which lacks \"%s\"", #got, got_,     \
                    part_);                                                                   \
    } while (0)

typedef struct test_case {
    const char *name;
    void (*fn)(void);
} test_case;

#define TEST_COUNT(tests) (sizeof(tests) / sizeof((tests)[0]))

static int run_tests(const test_case *tests, size_t count, int argc, char **argv)
{
    int passed = 0, failed = 0;
    for (size_t k = 0; k < count; k++) {
        bool selected = argc < 2;
        for (int a = 1; a < argc; a++)
            selected |= strstr(tests[k].name, argv[a]) != NULL;
        if (!selected)
            continue;
        checks_failed = 0;
        fflush(stdout);
        tests[k].fn();
        if (checks_failed) {
            printf("FAILED %s (%d checks)\n", tests[k].name, checks_failed);
            failed++;
        } else {
            passed++;
        }
    }
    printf("%d passed, %d failed\n", passed, failed);
    return failed ? 1 : 0;
}

#endif /* CHECK_H */
