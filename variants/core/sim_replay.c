/*
 * sim_replay.c: `--replay`, one step of SPEC §2 from each of a sequence of given states: what
 * the reference rules make of a state another program printed. The harness judges a program
 * step by step with it (harness/programs/steps.py): a program's step k+1 is compared with the
 * successor of its own step k, so the chaos of the whole trajectory never enters the verdict.
 * One process replays every state; the stepper is made once.
 *
 * Input (INPUT or stdin), whitespace-separated, one record a line:
 *
 *   N L r                  the scene, as SPEC §1's first line without S
 *   k i x y vx vy [p]      a state: N lines, i = 0 .. N-1 in order, one label k for all of them
 *
 * states following each other in any order of k. p (0 or 1, default 1) says whether particle
 * i's successor is printed: a state replayed only for some particles prints only those.
 * A centre outside [r, L-r] is clamped into it first, as a step's end clamps (the state of a
 * wrong program may be anywhere). Output, for each state, its printed particles in index
 * order, always to %.17g:
 *
 *   k+1 i x y vx vy EVENT PARTNER T
 *
 * EVENT is `free`, `pair` (PARTNER the other particle) or `wall` (PARTNER -1): the candidate
 * the walk accepted for i, at time T (0 when free). Bad input: one line and status 2.
 *
 * The same input in binary, for the harness's many perturbed copies of a state (formatting
 * and parsing millions of reals as text cost it seconds): the 8 bytes SIM_REPLAY_MAGIC, then
 * int64 N, double L, double r, then per state: int64 k, N x (double x, y, vx, vy), N flag
 * bytes; native byte order, no padding. Its successors come back in binary too (parsing them
 * as text cost the harness more than the replay itself): per printed particle one record of
 * SIM_REPLAY_RECORD bytes, int64 k+1, int32 i, double x, y, vx, vy, T, int32 PARTNER, uint8
 * EVENT (0 free, 1 pair, 2 wall), in the text form's order; native byte order, no padding.
 * harness/programs/steps.py reads it.
 */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sim_stepper.h"

#define SIM_REPLAY_FIELDS 7 /* k i x y vx vy p */
#define SIM_REPLAY_MAGIC "CBREPLAY"
#define SIM_REPLAY_MAGIC_LEN 8
/* The offsets of a binary successor record's fields (its layout: above). */
enum {
    SIM_REPLAY_AT_INDEX = 8,
    SIM_REPLAY_AT_VALUES = SIM_REPLAY_AT_INDEX + 4,
    SIM_REPLAY_AT_PARTNER = SIM_REPLAY_AT_VALUES + 5 * 8,
    SIM_REPLAY_AT_CODE = SIM_REPLAY_AT_PARTNER + 4,
    SIM_REPLAY_RECORD = SIM_REPLAY_AT_CODE + 1
};
_Static_assert(SIM_REPLAY_RECORD == 57, "the harness reads 57-byte successor records");

/* A cursor over the input's lines. */
typedef struct replay_reader {
    const char *next, *end;
    long line;
} replay_reader;

/* The tokens of the next non-blank line, at most `max` (more: count max + 1). Returns the
 * count, or -1 at the end of the input. */
static int next_line(replay_reader *rd, const char **tok, size_t *tlen, int max)
{
    while (rd->next < rd->end) {
        const char *p = rd->next, *eol = memchr(p, '\n', (size_t)(rd->end - p));
        if (!eol)
            eol = rd->end;
        rd->next = eol < rd->end ? eol + 1 : eol;
        rd->line++;
        int count = 0;
        while (p < eol) {
            while (p < eol && (*p == ' ' || *p == '\t' || *p == '\r'))
                p++;
            if (p == eol)
                break;
            const char *start = p;
            while (p < eol && *p != ' ' && *p != '\t' && *p != '\r')
                p++;
            if (count < max) {
                tok[count] = start;
                tlen[count] = (size_t)(p - start);
            }
            if (count <= max)
                count++;
        }
        if (count)
            return count;
    }
    return -1;
}

static bool to_double(const char *tok, size_t len, double *out)
{
    char buf[SIM_REAL_TEXT_MAX];
    if (len == 0 || len >= sizeof buf)
        return false;
    memcpy(buf, tok, len);
    buf[len] = '\0';
    char *end;
    errno = 0;
    *out = strtod(buf, &end);
    return *end == '\0' && isfinite(*out);
}

static bool to_long(const char *tok, size_t len, long long lo, long long hi, long long *out)
{
    char buf[32];
    if (len == 0 || len >= sizeof buf)
        return false;
    memcpy(buf, tok, len);
    buf[len] = '\0';
    char *end;
    errno = 0;
    *out = strtoll(buf, &end, 10);
    return *end == '\0' && errno != ERANGE && *out >= lo && *out <= hi;
}

/* One line of error; line 0: the binary form (its message names the record). */
static int bad(const char *name, long line, const char *what)
{
    if (line > 0)
        fprintf(stderr, "%s: replay: line %ld: %s\n", name, line, what);
    else
        fprintf(stderr, "%s: replay: %s\n", name, what);
    return SIM_EXIT_USAGE;
}

/* The scene line. Returns SIM_EXIT_OK or the status after printing why. */
static int read_scene(const char *name, replay_reader *rd, sim_header *h)
{
    const char *tok[4];
    size_t len[4];
    const int count = next_line(rd, tok, len, 3);
    if (count != 3)
        return bad(name, rd->line > 0 ? rd->line : 1, "expected the scene line `N L r`");
    long long n;
    if (!to_long(tok[0], len[0], 0, SIM_N_MAX, &n))
        return bad(name, rd->line, "N must be an integer in [0, 2^31)");
    if (!to_double(tok[1], len[1], &h->L) || !to_double(tok[2], len[2], &h->r) || h->r <= 0 ||
        2 * h->r > h->L)
        return bad(name, rd->line, "L and r must be finite reals with r > 0 and 2r <= L");
    h->n = (int32_t)n;
    h->steps = 0;
    h->mode = SIM_MODE_PRINT;
    return SIM_EXIT_OK;
}

/* The next state into w, its label into *k and its print flags into show. Returns SIM_EXIT_OK,
 * -1 at the end of the input, or the status after printing why. */
static int read_state(const char *name, replay_reader *rd, sim_world *w, long long *k,
                      unsigned char *show)
{
    char what[SIM_MSG_LEN];
    for (int32_t i = 0; i < w->n; i++) {
        const char *tok[SIM_REPLAY_FIELDS];
        size_t len[SIM_REPLAY_FIELDS];
        const int count = next_line(rd, tok, len, SIM_REPLAY_FIELDS);
        if (count < 0) {
            if (i == 0)
                return -1;
            snprintf(what, sizeof what, "the state of step %lld ends at particle %ld of %ld",
                     *k, (long)i, (long)w->n);
            return bad(name, rd->line, what);
        }
        if (count < SIM_REPLAY_FIELDS - 1 || count > SIM_REPLAY_FIELDS)
            return bad(name, rd->line, "expected `k i x y vx vy [p]`");
        long long step, index, flag = 1;
        if (!to_long(tok[0], len[0], 0, INT64_MAX - 1, &step))
            return bad(name, rd->line, "the step must be an integer >= 0");
        if (i > 0 && step != *k) {
            snprintf(what, sizeof what, "step %lld in the middle of the state of step %lld", step,
                     *k);
            return bad(name, rd->line, what);
        }
        *k = step;
        if (!to_long(tok[1], len[1], 0, SIM_N_MAX, &index) || index != i) {
            snprintf(what, sizeof what, "expected particle %ld of the state of step %lld",
                     (long)i, step);
            return bad(name, rd->line, what);
        }
        double v[4];
        for (int f = 0; f < 4; f++)
            if (!to_double(tok[2 + f], len[2 + f], &v[f])) {
                snprintf(what, sizeof what, "particle %ld: field %d is not a finite real",
                         (long)i, 3 + f);
                return bad(name, rd->line, what);
            }
        if (count == SIM_REPLAY_FIELDS && !to_long(tok[6], len[6], 0, 1, &flag))
            return bad(name, rd->line, "the print flag must be 0 or 1");
        const sim_real lo = w->lo, hi = w->hi, x = (sim_real)v[0], y = (sim_real)v[1];
        w->x[i] = x < lo ? lo : (x > hi ? hi : x);
        w->y[i] = y < lo ? lo : (y > hi ? hi : y);
        w->vx[i] = (sim_real)v[2];
        w->vy[i] = (sim_real)v[3];
        show[i] = (unsigned char)flag;
    }
    return SIM_EXIT_OK;
}

/* The binary form's cursor: the next byte, the end, the record (state) number from 1. */
typedef struct replay_bytes {
    const unsigned char *next, *end;
    long record;
} replay_bytes;

static bool take(replay_bytes *rb, void *out, size_t len)
{
    if ((size_t)(rb->end - rb->next) < len)
        return false;
    memcpy(out, rb->next, len);
    rb->next += len;
    return true;
}

static int read_scene_binary(const char *name, replay_bytes *rb, sim_header *h)
{
    int64_t n;
    rb->next += SIM_REPLAY_MAGIC_LEN;
    if (!take(rb, &n, sizeof n) || !take(rb, &h->L, sizeof h->L) || !take(rb, &h->r, sizeof h->r))
        return bad(name, 0, "the binary scene (N, L, r) is cut short");
    if (n < 0 || n > SIM_N_MAX)
        return bad(name, 0, "N must be an integer in [0, 2^31)");
    if (!isfinite(h->L) || !isfinite(h->r) || h->r <= 0 || 2 * h->r > h->L)
        return bad(name, 0, "L and r must be finite reals with r > 0 and 2r <= L");
    h->n = (int32_t)n;
    h->steps = 0;
    h->mode = SIM_MODE_PRINT;
    return SIM_EXIT_OK;
}

/* read_state for the binary form; errors name the record (state) instead of a line. */
static int read_state_binary(const char *name, replay_bytes *rb, sim_world *w, long long *k,
                             unsigned char *show)
{
    if (rb->next == rb->end)
        return -1;
    rb->record++;
    char what[SIM_MSG_LEN];
    int64_t label;
    if (!take(rb, &label, sizeof label) ||
        (size_t)(rb->end - rb->next) < (size_t)w->n * (4 * sizeof(double) + 1)) {
        snprintf(what, sizeof what, "binary state %ld is cut short", rb->record);
        return bad(name, 0, what);
    }
    if (label < 0 || label == INT64_MAX) {
        snprintf(what, sizeof what, "binary state %ld: the step must be an integer >= 0",
                 rb->record);
        return bad(name, 0, what);
    }
    *k = label;
    for (int32_t i = 0; i < w->n; i++) {
        double v[4];
        memcpy(v, rb->next, sizeof v); /* the length was checked for the whole state */
        rb->next += sizeof v;
        for (int f = 0; f < 4; f++)
            if (!isfinite(v[f])) {
                snprintf(what, sizeof what, "binary state %ld: particle %ld: value %d is not "
                         "a finite real", rb->record, (long)i, f + 1);
                return bad(name, 0, what);
            }
        const sim_real lo = w->lo, hi = w->hi, x = (sim_real)v[0], y = (sim_real)v[1];
        w->x[i] = x < lo ? lo : (x > hi ? hi : x);
        w->y[i] = y < lo ? lo : (y > hi ? hi : y);
        w->vx[i] = (sim_real)v[2];
        w->vy[i] = (sim_real)v[3];
    }
    for (int32_t i = 0; i < w->n; i++) {
        show[i] = *rb->next++;
        if (show[i] > 1) {
            snprintf(what, sizeof what, "binary state %ld: particle %ld: the print flag must "
                     "be 0 or 1", rb->record, (long)i);
            return bad(name, 0, what);
        }
    }
    return SIM_EXIT_OK;
}

/* What the walk accepted for each particle in the step just taken: its kind ('f', 'p',
 * 'w'), partner and time. */
static void note_events(const sim_stepper *s, char *kind, int32_t *partner, sim_real *t)
{
    for (size_t k = 0; k < s->pair_moves_len; k++) {
        const sim_cand c = s->pair_moves[k];
        kind[c.i] = kind[c.j] = 'p';
        partner[c.i] = c.j;
        partner[c.j] = c.i;
        t[c.i] = t[c.j] = c.t;
    }
    for (size_t k = 0; k < s->wall_moves_len; k++) {
        const sim_cand c = s->wall_moves[k];
        kind[c.i] = 'w';
        partner[c.i] = -1;
        t[c.i] = c.t;
    }
}

static int write_successor(FILE *out, const sim_world *w, long long k, const unsigned char *show,
                           const char *kind, const int32_t *partner, const sim_real *t)
{
    static const char *const names[] = {['f'] = "free", ['p'] = "pair", ['w'] = "wall"};
    char q[4][40], tb[40];
    for (int32_t i = 0; i < w->n; i++) {
        if (!show[i])
            continue;
        sim_format_real(q[0], sizeof q[0], w->x[i], true);
        sim_format_real(q[1], sizeof q[1], w->y[i], true);
        sim_format_real(q[2], sizeof q[2], w->vx[i], true);
        sim_format_real(q[3], sizeof q[3], w->vy[i], true);
        sim_format_real(tb, sizeof tb, t[i], true);
        if (fprintf(out, "%lld %ld %s %s %s %s %s %ld %s\n", k + 1, (long)i, q[0], q[1], q[2],
                    q[3], names[(unsigned char)kind[i]], (long)partner[i], tb) < 0)
            return -1;
    }
    return 0;
}

/* write_successor in the binary form, through `buf` (SIM_REPLAY_RECORD bytes a particle). */
static int write_successor_binary(FILE *out, const sim_world *w, long long k,
                                  const unsigned char *show, const char *kind,
                                  const int32_t *partner, const sim_real *t, unsigned char *buf)
{
    const int64_t label = k + 1;
    unsigned char *p = buf;
    for (int32_t i = 0; i < w->n; i++) {
        if (!show[i])
            continue;
        const double v[5] = {(double)w->x[i], (double)w->y[i], (double)w->vx[i],
                             (double)w->vy[i], (double)t[i]};
        const uint8_t code = kind[i] == 'p' ? 1 : (kind[i] == 'w' ? 2 : 0);
        memcpy(p, &label, sizeof label);
        memcpy(p + SIM_REPLAY_AT_INDEX, &i, sizeof i);
        memcpy(p + SIM_REPLAY_AT_VALUES, v, sizeof v);
        memcpy(p + SIM_REPLAY_AT_PARTNER, &partner[i], sizeof partner[i]);
        p[SIM_REPLAY_AT_CODE] = code;
        p += SIM_REPLAY_RECORD;
    }
    const size_t len = (size_t)(p - buf);
    return fwrite(buf, 1, len, out) == len ? 0 : -1;
}

int sim_replay(FILE *out, const char *name, const char *text, size_t len, int threads)
{
    replay_reader rd = {text, text + len, 0};
    replay_bytes rb = {(const unsigned char *)text, (const unsigned char *)text + len, 0};
    const bool binary = len >= SIM_REPLAY_MAGIC_LEN &&
                        memcmp(text, SIM_REPLAY_MAGIC, SIM_REPLAY_MAGIC_LEN) == 0;
    sim_header h;
    int rc = binary ? read_scene_binary(name, &rb, &h) : read_scene(name, &rd, &h);
    if (rc != SIM_EXIT_OK)
        return rc;
    sim_world w;
    if (sim_world_alloc(&w, &h)) {
        fprintf(stderr, "%s: out of memory for N=%ld particles\n", name, (long)h.n);
        return SIM_EXIT_RUNTIME;
    }
    const size_t n = (size_t)h.n + 1;
    unsigned char *show = malloc(n);
    char *kind = malloc(n);
    int32_t *partner = malloc(n * sizeof *partner);
    sim_real *t = malloc(n * sizeof *t);
    unsigned char *record = binary ? malloc(n * SIM_REPLAY_RECORD) : NULL;
    sim_stepper *s = show && kind && partner && t && (record || !binary)
                         ? sim_stepper_create(&w, &sim_variant_def, threads) : NULL;
    if (!s) {
        fprintf(stderr, "%s: out of memory for N=%ld particles\n", name, (long)h.n);
        rc = SIM_EXIT_RUNTIME;
    }
    sim_stats stats = {0};
    long long k = 0;
    while (rc == SIM_EXIT_OK && h.n > 0) {
        const int got = binary ? read_state_binary(name, &rb, &w, &k, show)
                               : read_state(name, &rd, &w, &k, show);
        if (got < 0)
            break;
        if (got != SIM_EXIT_OK) {
            rc = got;
            break;
        }
        /* A new state, not the stepper's last: its wall candidates must be found afresh. */
        s->walls_ready = false;
        if (sim_step(s, &w, &stats)) {
            fprintf(stderr, "%s: out of memory in step %lld\n", name, k);
            rc = SIM_EXIT_RUNTIME;
            break;
        }
        memset(kind, 'f', n);
        memset(partner, 0xff, n * sizeof *partner);
        memset(t, 0, n * sizeof *t);
        note_events(s, kind, partner, t);
        if (binary ? write_successor_binary(out, &w, k, show, kind, partner, t, record)
                   : write_successor(out, &w, k, show, kind, partner, t)) {
            fprintf(stderr, "%s: cannot write the output: %s\n", name, strerror(errno));
            rc = SIM_EXIT_RUNTIME;
        }
    }
    if (s)
        sim_stepper_destroy(s);
    free(show);
    free(kind);
    free(partner);
    free(t);
    free(record);
    sim_world_free(&w);
    return rc;
}
