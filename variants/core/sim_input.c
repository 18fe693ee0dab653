/*
 * sim_input.c: SPEC §1. Every rule of the input is checked here, once, and a broken one is
 * reported as the line it is on and what it broke; nothing in the input can crash the run.
 *
 * The input is read whole and NUL-terminated by the caller, so strtod/strtoll may look one
 * character past a token (they stop at the whitespace or the NUL that follows it).
 */
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sim_core.h"

/* How much of an offending token a message quotes (bytes of the input). */
#define SIM_TOKEN_QUOTE_MAX 40
/* Its text: each byte escaped to at most 4 characters, "..." and the NUL. */
#define SIM_QUOTE_TEXT_MAX (SIM_ESCAPED_MAX(SIM_TOKEN_QUOTE_MAX) + 4)

typedef struct token {
    const char *p;
    size_t len;
    long line;
} token;

static bool is_space(char c)
{
    return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\v' || c == '\f';
}

void sim_lexer_init(sim_lexer *lx, const char *text, size_t len)
{
    lx->text = text;
    lx->end = text + len;
    lx->line = 1;
}

/* The next token, or one of length 0 at the end (on the line where the input ended). */
static token next_token(sim_lexer *lx)
{
    const char *p = lx->text;
    while (p < lx->end && is_space(*p)) {
        if (*p == '\n' && p + 1 < lx->end)
            lx->line++;
        p++;
    }
    token t = {.p = p, .len = 0, .line = lx->line};
    while (p < lx->end && !is_space(*p))
        p++;
    t.len = (size_t)(p - t.p);
    lx->text = p;
    return t;
}

static int fail(sim_error *err, long line, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    err->line = line;
    vsnprintf(err->what, sizeof err->what, fmt, ap);
    va_end(ap);
    return -1;
}

size_t sim_escape(char *buf, size_t len, const char *s, size_t n)
{
    static const char hex[] = "0123456789abcdef";
    size_t k = 0;
    for (size_t i = 0; i < n && k + 5 <= len; i++) {
        const unsigned char c = (unsigned char)s[i];
        if (c >= 0x20 && c < 0x7f && c != '\\') {
            buf[k++] = (char)c;
        } else {
            buf[k++] = '\\';
            buf[k++] = 'x';
            buf[k++] = hex[c >> 4];
            buf[k++] = hex[c & 15];
        }
    }
    if (len)
        buf[k < len ? k : len - 1] = '\0';
    return k;
}

/* The token as a printable, bounded string for a message: a terminal must not read the
 * input's control bytes. */
static const char *quote(token t, char *buf, size_t len)
{
    const size_t shown = t.len < SIM_TOKEN_QUOTE_MAX ? t.len : SIM_TOKEN_QUOTE_MAX;
    const size_t k = sim_escape(buf, len, t.p, shown);
    if (t.len > shown && k + 4 <= len)
        memcpy(buf + k, "...", 4);
    return buf;
}

/* A token that must be present: a missing one is an error naming what was expected. */
static int need(sim_lexer *lx, token *t, const char *what, sim_error *err)
{
    *t = next_token(lx);
    if (t->len == 0)
        return fail(err, t->line, "%s: missing (the input ended)", what);
    return 0;
}

static int parse_int(sim_lexer *lx, const char *what, int64_t min, int64_t max, int64_t *out,
                     sim_error *err)
{
    token t;
    char q[SIM_QUOTE_TEXT_MAX];
    if (need(lx, &t, what, err))
        return -1;
    const char *digits = t.p + (t.p[0] == '+' || t.p[0] == '-');
    bool ok = digits < t.p + t.len;
    for (const char *c = digits; c < t.p + t.len; c++)
        ok &= *c >= '0' && *c <= '9';
    if (!ok)
        return fail(err, t.line, "%s: expected an integer, got '%s'", what, quote(t, q, sizeof q));
    errno = 0;
    const long long v = strtoll(t.p, NULL, 10);
    if (errno == ERANGE || v < min || v > max)
        return fail(err, t.line, "%s=%s is outside [%lld, %lld]", what, quote(t, q, sizeof q),
                    (long long)min, (long long)max);
    *out = v;
    return 0;
}

static int parse_real(sim_lexer *lx, const char *what, double *out, long *line, sim_error *err)
{
    token t;
    char q[SIM_QUOTE_TEXT_MAX];
    if (need(lx, &t, what, err))
        return -1;
    char *end;
    const double v = strtod(t.p, &end);
    if (end != t.p + t.len)
        return fail(err, t.line, "%s: expected a real number, got '%s'", what,
                    quote(t, q, sizeof q));
    if (!isfinite(v))
        return fail(err, t.line, "%s: expected a finite real, got '%s'", what,
                    quote(t, q, sizeof q));
    /* strtod also reads C's hexadecimal floats; the format is decimal. */
    if (memchr(t.p, 'x', t.len) || memchr(t.p, 'X', t.len))
        return fail(err, t.line, "%s: expected a decimal real, got '%s'", what,
                    quote(t, q, sizeof q));
    *out = v;
    if (line)
        *line = t.line;
    return 0;
}

int sim_parse_header(sim_lexer *lx, sim_header *h, sim_error *err)
{
    int64_t n, steps;
    long line;
    if (parse_int(lx, "N", 0, SIM_N_MAX, &n, err) || parse_real(lx, "L", &h->L, NULL, err) ||
        parse_real(lx, "r", &h->r, &line, err))
        return -1;
    if (!(h->r > 0))
        return fail(err, line, "r=%g: expected r > 0", h->r);
    if (!(2 * h->r <= h->L))
        return fail(err, line, "r=%g: expected 2r <= L (L=%g)", h->r, h->L);
    /* SPEC §4 draws speeds between L/(8r) and L/4: a tiny (denormal) r makes them infinite. */
    if (!isfinite(h->L / (8 * h->r)))
        return fail(err, line, "r=%g: the generated speed L/(8r) is not finite (L=%g)", h->r,
                    h->L);
    if (parse_int(lx, "S", 0, INT64_MAX, &steps, err))
        return -1;
    h->n = (int32_t)n;
    h->steps = steps;

    token t;
    char q[SIM_QUOTE_TEXT_MAX];
    if (need(lx, &t, "MODE", err))
        return -1;
    if (t.len == 5 && strncmp(t.p, "print", 5) == 0)
        h->mode = SIM_MODE_PRINT;
    else if (t.len == 4 && strncmp(t.p, "perf", 4) == 0)
        h->mode = SIM_MODE_PERF;
    else
        return fail(err, t.line, "MODE: expected 'print' or 'perf', got '%s'",
                    quote(t, q, sizeof q));
    return 0;
}

/* One coordinate of a listed particle, which must keep the disc inside the box. */
static int parse_coord(sim_lexer *lx, int64_t i, const char *name, double lo, double hi,
                       double *out, sim_error *err)
{
    char what[64];
    long line;
    snprintf(what, sizeof what, "particle %lld: %s", (long long)i, name);
    if (parse_real(lx, what, out, &line, err))
        return -1;
    if (!(*out >= lo && *out <= hi))
        return fail(err, line, "particle %lld: %s=%g is outside [%g, %g]", (long long)i, name,
                    *out, lo, hi);
    return 0;
}

int sim_parse_particles(sim_lexer *lx, const sim_header *h, sim_world *w, unsigned char *listed,
                        sim_error *err)
{
    const double lo = h->r, hi = h->L - h->r;
    char q[SIM_QUOTE_TEXT_MAX];
    for (int64_t count = 0;; count++) {
        const sim_lexer before = *lx;
        const token t = next_token(lx);
        if (t.len == 0)
            return 0;
        if (count == h->n)
            return fail(err, t.line, "unexpected '%s' after %lld particle lines (N=%lld)",
                        quote(t, q, sizeof q), (long long)count, (long long)h->n);
        *lx = before;
        int64_t i;
        char what[64];
        snprintf(what, sizeof what, "particle index (particle line %lld)", (long long)count + 1);
        if (parse_int(lx, what, 0, h->n > 0 ? h->n - 1 : -1, &i, err))
            return -1;
        if (listed[i])
            return fail(err, t.line, "particle %lld: duplicate index", (long long)i);
        listed[i] = 1;
        double x, y, vx, vy;
        char vname[64];
        if (parse_coord(lx, i, "x", lo, hi, &x, err) || parse_coord(lx, i, "y", lo, hi, &y, err))
            return -1;
        snprintf(vname, sizeof vname, "particle %lld: vx", (long long)i);
        if (parse_real(lx, vname, &vx, NULL, err))
            return -1;
        snprintf(vname, sizeof vname, "particle %lld: vy", (long long)i);
        if (parse_real(lx, vname, &vy, NULL, err))
            return -1;
        w->x[i] = (sim_real)x;
        w->y[i] = (sim_real)y;
        w->vx[i] = (sim_real)vx;
        w->vy[i] = (sim_real)vy;
    }
}
