/*
 * sim_output.c: SPEC §3. One line per particle in index order; reals with %.8f, or %.17g with
 * --precise (which round-trips a double exactly). Builds of other real types use the same
 * formats so that every build's output can be compared with the same tools.
 *
 * Why not printf for %.8f: glibc formats each real through multi-precision arithmetic, about
 * 0.7 us a number, so writing 10^4 particles took 28 ms, as long as grid's whole broad phase
 * for 3 steps, and it was serial. sim_fixed8 prints the same bytes from exact integer
 * arithmetic (a double is m * 2^e, so |v| * 10^8 is an exact 128-bit product, and printf's
 * rounding of that exact value, to nearest with ties to even, is done on the integers). Values
 * outside its range (|v| >= SIM_FIXED8_MAX, NaN, infinities) and __float128 go to the C
 * library; tests/c/test_core.c compares it with snprintf on millions of values and every tie.
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <omp.h>

#include "sim_core.h"

/* sim_fixed8 handles |v| below this: |v| * 10^8 < 10^18 fits a uint64_t. */
#define SIM_FIXED8_MAX 1e10
/* The %.8f scale. */
#define SIM_FIXED8_SCALE UINT64_C(100000000)
#define SIM_FIXED8_DIGITS 8
/* Longest text of the fast path, NUL included: a sign, 10 integer digits, the point, 8. */
#define SIM_FIXED8_TEXT_MAX (1 + 10 + 1 + SIM_FIXED8_DIGITS + 1)
/* Longest line: step, index, four reals, two counts, separators. */
#define SIM_LINE_MAX (2 * 24 + 4 * SIM_REAL_TEXT_MAX + 2 * 24 + 16)

/* 128-bit products: GCC and Clang have them on every 64-bit target. */
__extension__ typedef unsigned __int128 sim_u128;

/* "00" "01" ... "99": two digits per table read, half the divisions of one at a time. */
static const char digit_pairs[201] =
    "000102030405060708091011121314151617181920212223242526272829"
    "303132333435363738394041424344454647484950515253545556575859"
    "606162636465666768697071727374757677787980818283848586878889"
    "90919293949596979899";

/* The two decimal digits of d < 100 at p. */
static inline void put_pair(char *p, uint32_t d)
{
    memcpy(p, digit_pairs + 2 * d, 2);
}

/* Decimal digits of u at p; returns their count. Written in place from the last digit (a
 * copy of variable length from a scratch buffer was a call to memmove per number). */
static size_t put_u64(char *p, uint64_t u)
{
    size_t len = 1;
    for (uint64_t t = u; t >= 10; t /= 10)
        len++;
    size_t k = len;
    while (u >= 100) {
        k -= 2;
        put_pair(p + k, (uint32_t)(u % 100));
        u /= 100;
    }
    if (u >= 10)
        put_pair(p, (uint32_t)u);
    else
        p[0] = (char)('0' + u);
    return len;
}

static size_t put_i64(char *p, int64_t v)
{
    if (v < 0) {
        *p = '-';
        return 1 + put_u64(p + 1, (uint64_t)0 - (uint64_t)v);
    }
    return put_u64(p, (uint64_t)v);
}

/* printf("%.8f", v) at p; returns the length, or 0 when v is outside the fast path. */
size_t sim_fixed8(char *p, double v)
{
    if (!(fabs(v) < SIM_FIXED8_MAX))
        return 0;
    uint64_t bits;
    memcpy(&bits, &v, sizeof bits);
    const int biased = (int)(bits >> 52 & 0x7ff);
    const uint64_t frac = bits & ((UINT64_C(1) << 52) - 1);
    /* |v| = m * 2^e exactly. */
    const uint64_t m = biased ? frac | UINT64_C(1) << 52 : frac;
    const int e = biased ? biased - 1075 : -1074;
    uint64_t q; /* round(|v| * 10^8), ties to even */
    if (e >= 0) {
        q = (m << e) * SIM_FIXED8_SCALE; /* |v| < 10^10: m << e < 2^34 */
    } else {
        const sim_u128 prod = (sim_u128)m * SIM_FIXED8_SCALE; /* < 2^80 */
        const int s = -e;
        if (s >= 128) {
            q = 0; /* prod < 2^80 < half of 2^s */
        } else {
            const sim_u128 one = 1;
            const sim_u128 rem = prod & ((one << s) - 1), half = one << (s - 1);
            q = (uint64_t)(prod >> s);
            q += rem > half || (rem == half && (q & 1));
        }
    }
    size_t k = 0;
    if (bits >> 63)
        p[k++] = '-'; /* printf keeps the sign of -0.0 and of negatives that round to 0 */
    k += put_u64(p + k, q / SIM_FIXED8_SCALE);
    p[k++] = '.';
    /* The 8 fraction digits as four pairs, from two halves of 4 (32-bit divisions). */
    const uint32_t f = (uint32_t)(q % SIM_FIXED8_SCALE), f_hi = f / 10000, f_lo = f % 10000;
    put_pair(p + k, f_hi / 100);
    put_pair(p + k + 2, f_hi % 100);
    put_pair(p + k + 4, f_lo / 100);
    put_pair(p + k + 6, f_lo % 100);
    return k + SIM_FIXED8_DIGITS;
}

void sim_format_real(char *buf, size_t len, sim_real v, bool precise)
{
#if defined(SIM_REAL_F128)
    quadmath_snprintf(buf, len, precise ? "%.17Qg" : "%.8Qf", v);
#else
    if (!precise && len >= SIM_FIXED8_TEXT_MAX) {
        const size_t k = sim_fixed8(buf, (double)v);
        if (k) {
            buf[k] = '\0';
            return;
        }
    }
    snprintf(buf, len, precise ? "%.17g" : "%.8f", (double)v);
#endif
}

/* A real and a leading space at p; returns the length. */
static size_t put_real(char *p, sim_real v, bool precise)
{
    *p = ' ';
#if !defined(SIM_REAL_F128)
    if (!precise) {
        const size_t k = sim_fixed8(p + 1, (double)v);
        if (k)
            return 1 + k;
    }
#endif
    sim_format_real(p + 1, SIM_REAL_TEXT_MAX, v, precise);
    return 1 + strlen(p + 1);
}

/* Lines are formatted a chunk of SIM_OUT_LINES particles at a time into a buffer and written
 * with one fwrite (a call per line took the stream's lock and copied each line again: 10^4
 * lines cost 0.6 ms). On a team each chunk is one hand-over between threads, and on a loaded
 * machine a descheduled thread's turn waits a scheduler tick: chunks are long (docs/grid_bound.md
 * has the times). */
#define SIM_OUT_LINES 4096
#define SIM_OUT_CHUNK (SIM_OUT_LINES * SIM_LINE_MAX)
/* Below this many particles a block is formatted on one thread: a team's start costs more. */
#define SIM_OUT_PARALLEL_MIN 16384

/* The lines "prefix i x y vx vy" (+ " pcoll wcoll" when counts) of particles [i0, i1) at p;
 * returns their length, at most (i1 - i0) * SIM_LINE_MAX. */
static size_t format_lines(char *p, const sim_world *w, const char *prefix, size_t prefix_len,
                           int32_t i0, int32_t i1, bool precise, bool counts)
{
    size_t at = 0;
    for (int32_t i = i0; i < i1; i++) {
        char *line = p + at;
        memcpy(line, prefix, 24); /* whole: a constant length is inlined */
        size_t k = prefix_len;
        k += put_i64(line + k, i);
        k += put_real(line + k, w->x[i], precise);
        k += put_real(line + k, w->y[i], precise);
        k += put_real(line + k, w->vx[i], precise);
        k += put_real(line + k, w->vy[i], precise);
        if (counts) {
            line[k++] = ' ';
            k += put_i64(line + k, w->pcoll[i]);
            line[k++] = ' ';
            k += put_i64(line + k, w->wcoll[i]);
        }
        line[k++] = '\n';
        at += k;
    }
    return at;
}

/* "prefix i x y vx vy" (+ " pcoll wcoll" when counts) for every particle, in index order. The
 * team formats chunks side by side (formatting is most of the time: about 40 ns a real) and
 * writes them in order, each thread its next chunk while another writes. */
static int write_block(FILE *out, const sim_world *w, int64_t step, bool precise, bool counts)
{
    /* The step and its space, the same on every line. */
    char prefix[24];
    size_t prefix_len = put_i64(prefix, step);
    prefix[prefix_len++] = ' ';
    const int32_t chunks = (w->n + SIM_OUT_LINES - 1) / SIM_OUT_LINES;
    const int team = w->n >= SIM_OUT_PARALLEL_MIN ? omp_get_max_threads() : 1;
    int failed = 0;
#pragma omp parallel num_threads(team) if (team > 1)
    {
        char *chunk = malloc(SIM_OUT_CHUNK);
        int mine_failed = !chunk;
#pragma omp for schedule(static, 1) ordered
        for (int32_t c = 0; c < chunks; c++) {
            const int32_t i0 = c * SIM_OUT_LINES;
            const int32_t i1 = w->n - i0 < SIM_OUT_LINES ? w->n : i0 + SIM_OUT_LINES;
            const size_t len =
                mine_failed ? 0 : format_lines(chunk, w, prefix, prefix_len, i0, i1, precise, counts);
#pragma omp ordered
            if (mine_failed || (!failed && fwrite(chunk, 1, len, out) != len))
                failed = 1;
        }
        free(chunk);
    }
    return failed ? -1 : 0;
}

int sim_write_state(FILE *out, const sim_world *w, int64_t step, bool precise)
{
    return write_block(out, w, step, precise, false);
}

int sim_write_final(FILE *out, const sim_world *w, int64_t step, bool precise)
{
    return write_block(out, w, step, precise, true);
}

/* s as a JSON string: quotes, backslashes and control characters escaped; other bytes, UTF-8
 * included, as they are. */
static void put_json_string(FILE *out, const char *s)
{
    fputc('"', out);
    for (const unsigned char *p = (const unsigned char *)s; *p; p++) {
        if (*p == '"' || *p == '\\')
            fprintf(out, "\\%c", *p);
        else if (*p == '\n')
            fputs("\\n", out);
        else if (*p == '\t')
            fputs("\\t", out);
        else if (*p < 0x20)
            fprintf(out, "\\u%04x", *p);
        else
            fputc(*p, out);
    }
    fputc('"', out);
}

/* {"step":1,"row":2}: the nonzero terms of a count, in a fixed order. */
static void put_count(FILE *out, const char *key, const sim_count *c)
{
    const char *names[] = {"step", "row", "pair", "tile"};
    const int values[] = {c->per_step, c->per_row, c->per_pair, c->per_tile};
    fprintf(out, "\"%s\":{", key);
    for (int k = 0, first = 1; k < 4; k++)
        if (values[k]) {
            fprintf(out, "%s\"%s\":%d", first ? "" : ",", names[k], values[k]);
            first = 0;
        }
    fputc('}', out);
}

static void put_sync(FILE *out, const sim_sync *s)
{
    if (!s) {
        fputs("null", out);
        return;
    }
    fputc('{', out);
    put_count(out, "regions", &s->regions);
    fputc(',', out);
    put_count(out, "nested_regions", &s->nested_regions);
    fputc(',', out);
    put_count(out, "barriers", &s->barriers);
    fputc(',', out);
    put_count(out, "grabs", &s->grabs);
    fprintf(out, ",\"tile\":%ld}", (long)s->tile);
}

int sim_describe(FILE *out, const sim_variant *v)
{
    fputs("{\"name\":", out);
    put_json_string(out, v->name);
    fputs(",\"summary\":", out);
    put_json_string(out, v->summary ? v->summary : "");
    fprintf(out, ",\"exact\":%s,\"parallel\":%s,\"all_pairs\":%s,\"repairs\":",
            v->exact ? "true" : "false", v->parallel ? "true" : "false",
            v->all_pairs ? "true" : "false");
    if (v->repairs)
        put_json_string(out, v->repairs);
    else
        fputs("null", out);
    fprintf(out, ",\"mpi\":%s,\"sync\":", v->mpi ? "true" : "false");
    put_sync(out, v->sync);
    fputs("}\n", out);
    return ferror(out) ? -1 : 0;
}
