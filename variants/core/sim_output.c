/*
 * sim_output.c: SPEC §3. One line per particle in index order; reals with %.8f, or %.17g with
 * --precise (which round-trips a double exactly). Builds of other real types use the same
 * formats so that every build's output can be compared with the same tools.
 */
#include <stdio.h>

#include "sim_core.h"

/* Longest formatted real: %.8f of a coordinate up to SIM's limits, or %.17g. */
#define SIM_REAL_TEXT_MAX 64

void sim_format_real(char *buf, size_t len, sim_real v, bool precise)
{
#if defined(SIM_REAL_F128)
    quadmath_snprintf(buf, len, precise ? "%.17Qg" : "%.8Qf", v);
#else
    snprintf(buf, len, precise ? "%.17g" : "%.8f", (double)v);
#endif
}

/* "prefix i x y vx vy" (+ " pcoll wcoll" when counts) for every particle. */
static int write_block(FILE *out, const sim_world *w, int64_t step, bool precise, bool counts)
{
    char x[SIM_REAL_TEXT_MAX], y[SIM_REAL_TEXT_MAX], vx[SIM_REAL_TEXT_MAX], vy[SIM_REAL_TEXT_MAX];
    for (int32_t i = 0; i < w->n; i++) {
        sim_format_real(x, sizeof x, w->x[i], precise);
        sim_format_real(y, sizeof y, w->y[i], precise);
        sim_format_real(vx, sizeof vx, w->vx[i], precise);
        sim_format_real(vy, sizeof vy, w->vy[i], precise);
        int rc = counts ? fprintf(out, "%lld %ld %s %s %s %s %lld %lld\n", (long long)step,
                                  (long)i, x, y, vx, vy, (long long)w->pcoll[i],
                                  (long long)w->wcoll[i])
                        : fprintf(out, "%lld %ld %s %s %s %s\n", (long long)step, (long)i, x, y,
                                  vx, vy);
        if (rc < 0)
            return -1;
    }
    return 0;
}

int sim_write_state(FILE *out, const sim_world *w, int64_t step, bool precise)
{
    return write_block(out, w, step, precise, false);
}

int sim_write_final(FILE *out, const sim_world *w, int64_t step, bool precise)
{
    return write_block(out, w, step, precise, true);
}
