/*
 * sim_gen.c: SPEC §4, the particles the input does not list, from one splitmix64 stream.
 * The seed comes from --seed (default 1), never from the clock, so every run is repeatable.
 */
#include <math.h>
#include <stdlib.h>

#include "sim_core.h"

/* splitmix64 constants (Steele, Lea and Flood 2014; the Java SplittableRandom mixer). */
#define SIM_SPLITMIX_GAMMA UINT64_C(0x9E3779B97F4A7C15)
#define SIM_SPLITMIX_MUL1 UINT64_C(0xBF58476D1CE4E5B9)
#define SIM_SPLITMIX_MUL2 UINT64_C(0x94D049BB133111EB)
/* 2^-53: maps the top 53 bits of a draw to a double in [0, 1). */
#define SIM_TWO_POW_MINUS_53 (1.0 / 9007199254740992.0)
#define SIM_TWO_PI 6.283185307179586476925286766559

uint64_t sim_splitmix64_next(uint64_t *state)
{
    *state += SIM_SPLITMIX_GAMMA;
    uint64_t z = *state;
    z = (z ^ (z >> 30)) * SIM_SPLITMIX_MUL1;
    z = (z ^ (z >> 27)) * SIM_SPLITMIX_MUL2;
    return z ^ (z >> 31);
}

double sim_uniform(uint64_t *state)
{
    return (double)(sim_splitmix64_next(state) >> 11) * SIM_TWO_POW_MINUS_53;
}

/* Particles per chunk of the generation: a chunk's draws start at its own place in the stream. */
#define SIM_GEN_CHUNK 4096
/* Below this many chunks one pass is quicker than starting the team (about 1 ms of a small
 * scene's run). */
#define SIM_GEN_TEAM_CHUNKS 16

/* Fill the unlisted particles of [i0, i1) from the stream state that precedes their first
 * draw. */
static void generate_range(sim_world *w, const sim_header *h, const unsigned char *listed,
                           uint64_t state, int32_t i0, int32_t i1)
{
    /* In double, from the input's double L and r, whatever the build's real type: every build
     * starts from the same scene, rounded to its type. */
    const double L = h->L, r = h->r;
    const double a = L / (8 * r), b = L / 4;
    const double lo = a < b ? a : b, hi = a < b ? b : a;
    for (int32_t i = i0; i < i1; i++) {
        if (listed[i])
            continue;
        const double u1 = sim_uniform(&state), u2 = sim_uniform(&state);
        const double u3 = sim_uniform(&state), u4 = sim_uniform(&state);
        const double speed = lo + u3 * (hi - lo), angle = SIM_TWO_PI * u4;
        w->x[i] = (sim_real)(r + u1 * (L - 2 * r));
        w->y[i] = (sim_real)(r + u2 * (L - 2 * r));
        w->vx[i] = (sim_real)(speed * cos(angle));
        w->vy[i] = (sim_real)(speed * sin(angle));
    }
}

/* The stream is a counter (the state advances by SIM_SPLITMIX_GAMMA a draw), so the state
 * before draw d is seed + d * gamma: chunks of particles are generated side by side, each from
 * where the unlisted particles before it leave the stream, with the same draws as one pass. */
void sim_generate(sim_world *w, const sim_header *h, const unsigned char *listed, uint64_t seed)
{
    const int32_t chunks = (w->n + SIM_GEN_CHUNK - 1) / SIM_GEN_CHUNK;
    if (chunks < SIM_GEN_TEAM_CHUNKS) {
        generate_range(w, h, listed, seed, 0, w->n);
        return;
    }
    /* drawn[c]: the draws before chunk c (4 an unlisted particle). */
    uint64_t *drawn = malloc(((size_t)chunks + 1) * sizeof *drawn);
    if (!drawn) { /* one pass instead */
        generate_range(w, h, listed, seed, 0, w->n);
        return;
    }
    drawn[0] = 0;
#pragma omp parallel for schedule(static)
    for (int32_t c = 0; c < chunks; c++) {
        const int32_t i1 = w->n - c * SIM_GEN_CHUNK < SIM_GEN_CHUNK ? w->n : (c + 1) * SIM_GEN_CHUNK;
        uint64_t m = 0;
        for (int32_t i = c * SIM_GEN_CHUNK; i < i1; i++)
            m += !listed[i];
        drawn[c + 1] = 4 * m;
    }
    for (int32_t c = 0; c < chunks; c++)
        drawn[c + 1] += drawn[c];
#pragma omp parallel for schedule(static)
    for (int32_t c = 0; c < chunks; c++) {
        const int32_t i1 = w->n - c * SIM_GEN_CHUNK < SIM_GEN_CHUNK ? w->n : (c + 1) * SIM_GEN_CHUNK;
        generate_range(w, h, listed, seed + drawn[c] * SIM_SPLITMIX_GAMMA, c * SIM_GEN_CHUNK, i1);
    }
    free(drawn);
}
