/*
 * sim_sort.c: the pair candidates of a step, merged from the finder's buffers and sorted by the
 * SPEC §2 key (t ascending; pair before wall; smaller i; smaller j), less the pairs a wall comes
 * first for; and the same sort for the tests (sim_sort_candidates).
 */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "sim_stepper.h"

/* cand_cmp(a, b) < 0: the SPEC §2 key, t ascending; pair before wall; smaller i; smaller j.
 * Total, so no sort's instability can show. The one definition of the key; cand_cmp is its
 * qsort form. */
static inline bool cand_before(const sim_cand *a, const sim_cand *b)
{
    if (a->t != b->t)
        return a->t < b->t;
    const int a_wall = a->j == SIM_WALL, b_wall = b->j == SIM_WALL;
    if (a_wall != b_wall)
        return a_wall < b_wall;
    if (a->i != b->i)
        return a->i < b->i;
    return a->j < b->j;
}

static int cand_cmp(const void *pa, const void *pb)
{
    const sim_cand *a = pa, *b = pb;
    return cand_before(a, b) ? -1 : cand_before(b, a);
}

/* The sort's buckets: sorting by bucket is one counting pass over the candidates (histogram,
 * prefix sums, scatter), and a step's candidates spread over about half as many buckets as
 * there are candidates, so a bucket holds one to three: cand_cmp orders those in place.
 * Between SIM_SORT_MIN_BITS and SIM_SORT_MAX_BITS bits; the histogram, 4 bytes a bucket, is
 * an eighth of the candidates' own size. A fixed number of buckets does not scale: 2^13 of them
 * leave a million particles' 1.8 million pair candidates a step about 220 to a bucket, each
 * sorted by qsort (docs/grid_bound.md has the times). */
#define SIM_SORT_MIN_BITS 8
#define SIM_SORT_MAX_BITS 26
/* Buckets longer than this are checked for order, and sorted by qsort if need be, before the
 * insertion pass. */
#define SIM_INSERTION_MAX 16
/* Candidates ahead whose particles' wall times are prefetched while the sort drops the pairs
 * a wall comes first for (sort_candidates): wall_t is 8 MB at a million particles, read at
 * random. */
#define SIM_WALL_T_AHEAD 32

/* The bucket of t among 2^bits + 1: 0 for t <= 0 (exactly 0 is common: the walls of the
 * particles a wall stopped the step before), then 2^bits equally wide buckets over (0, 1].
 * From the bits of t + 1, a double in [1, 2] for every candidate time (SPEC §2): the
 * addition is monotone in t, and above 1.0 its bits count up in steps of 2^-52, so
 * ceil((bits - bits of 1.0) / 2^(52 - bits)), clipped to [0, 2^bits], is monotone in t too:
 * sorting by bucket and then by cand_cmp within buckets is sorting by cand_cmp (a time
 * outside [0, 1], or within 2^-53 of 0, only lands in an end bucket). Integer selects: the
 * floating-point form compiled to branches, which mispredicted on the zeros. */
static inline uint32_t cand_bucket(sim_real t, int shift, int64_t top)
{
    const double d = (double)t + 1.0;
    int64_t u;
    memcpy(&u, &d, sizeof u);
    u -= INT64_C(0x3FF0000000000000); /* the bits of 1.0 */
    u = u > 0 ? u : 0;
    const int64_t k = (u + ((INT64_C(1) << shift) - 1)) >> shift;
    return (uint32_t)(k < top ? k : top);
}

/* Order a[lo, hi), a long bucket, by cand_cmp. Long buckets are many equal times (t = 0:
 * touching discs, or in a list with walls those of particles a wall stopped the step before),
 * which the stable scatter often leaves in order already: checked first, qsort only if not. */
static void finish_long_bucket(sim_cand *a, size_t lo, size_t hi)
{
    size_t k = lo + 1;
    while (k < hi && !cand_before(&a[k], &a[k - 1]))
        k++;
    if (k < hi)
        qsort(a + lo, hi - lo, sizeof *a, cand_cmp);
}

/* The sort's bits for n candidates: 2^bits buckets over (0, 1], at least n/2. */
static int sort_bits(size_t n)
{
    int bits = SIM_SORT_MIN_BITS;
    while (bits < SIM_SORT_MAX_BITS && ((size_t)2 << bits) < n)
        bits++;
    return bits;
}

/* The entries of sort_candidates' histogram for n candidates. */
static size_t sort_hist_len(size_t n)
{
    return ((size_t)1 << sort_bits(n)) + 2;
}

/* Source c[0, m) counted into count[bucket >> cshift]; where wall_t is not NULL, the pairs a
 * wall of either particle comes before are dropped first (sort_candidates says why), the
 * source compacted in place. Returns the candidates kept. */
static size_t count_source(sim_cand *restrict c, size_t m, const sim_real *restrict wall_t,
                           int shift, int64_t top, int cshift, uint32_t *restrict count)
{
    if (!wall_t) {
        for (size_t k = 0; k < m; k++)
            count[cand_bucket(c[k].t, shift, top) >> cshift]++;
        return m;
    }
    size_t out = 0;
    for (size_t k = 0; k < m; k++) {
#if defined(__GNUC__)
        if (k + SIM_WALL_T_AHEAD < m) {
            __builtin_prefetch(&wall_t[c[k + SIM_WALL_T_AHEAD].i]);
            __builtin_prefetch(&wall_t[c[k + SIM_WALL_T_AHEAD].j]);
        }
#endif
        const sim_cand e = c[k];
        const unsigned keep = !((wall_t[e.i] < e.t) | (wall_t[e.j] < e.t));
        c[out] = e;
        out += keep;
        count[cand_bucket(e.t, shift, top) >> cshift] += keep;
    }
    return out;
}

/* a[lo, end[buckets - 1]) scattered by bucket, bucket b ending at end[b]: each bucket ordered
 * by cand_cmp. Long buckets first (rare: see finish_long_bucket), then one insertion pass:
 * buckets hold a few candidates, and an insertion never crosses into an earlier bucket (its
 * times are all smaller), so the pass costs one comparison a candidate and a move per pair out
 * of order. */
static void finish_buckets(sim_cand *a, size_t lo, const uint32_t *end, uint32_t buckets)
{
    for (uint32_t b = 0; b < buckets; b++) {
        const size_t from = b ? lo + end[b - 1] : lo, to = lo + end[b];
        if (to - from > SIM_INSERTION_MAX)
            finish_long_bucket(a, from, to);
    }
    const size_t hi = buckets ? lo + end[buckets - 1] : lo;
    for (size_t k = lo + 1; k < hi; k++) {
        if (!cand_before(&a[k], &a[k - 1]))
            continue;
        const sim_cand c = a[k];
        size_t m = k;
        do {
            a[m] = a[m - 1];
            m--;
        } while (m > lo && cand_before(&c, &a[m - 1]));
        a[m] = c;
    }
}

/* Sort the candidates of src[0..sources) (src[s] holding len[s], n in all) into dst by cand_cmp,
 * and return how many there are in dst: a counting sort into about n/2 buckets of t (stable,
 * O(n): qsort's merge sort took 0.6 ms on a step's few thousand candidates, and a two-pass
 * 11-bit radix sort 43 us), straight from the writers' buffers, then cand_cmp within the
 * buckets, which are short (finish_long_bucket takes the rest). Where wall_t is not NULL the
 * sources are pairs, and the pass that counts them first drops every pair that a wall of one of
 * its particles comes before (wall_t[i] or wall_t[j] < t: at equal times the pair comes first),
 * compacting each source in place and shortening len[s]: the greedy walk would refuse it
 * (sim_resolve.c says why) and it changes nothing else, and the sort, the walk and the motion
 * then see only the pairs that can be accepted (about a sixth of the million particles' pairs
 * after the first step, a twentieth of the report benchmark's). hist holds sort_hist_len(n)
 * entries. */
static size_t sort_candidates(sim_cand *const *src, size_t *len, int sources,
                              const sim_real *restrict wall_t, uint32_t *restrict hist,
                              sim_cand *restrict dst, size_t n)
{
    /* The scatter's stores land anywhere in dst, cold since the last step: fetched first in
     * one stream (for writing), while the histogram is counted. */
#if defined(__GNUC__)
    for (size_t k = 0; k < n; k += SIM_CACHE_LINE / sizeof *dst)
        __builtin_prefetch(&dst[k], 1);
#endif
    const int bits = sort_bits(n);
    const uint32_t buckets = (UINT32_C(1) << bits) + 1;
    const int shift = 52 - bits;
    const int64_t top = (int64_t)buckets - 1;
    /* hist[b + 1] counts bucket b; the prefix sums make hist[b] where bucket b begins, and
     * the scatter advances it to where bucket b ends. */
    memset(hist, 0, (buckets + 1) * sizeof *hist);
    size_t kept = 0;
    for (int s = 0; s < sources; s++) {
        len[s] = count_source(src[s], len[s], wall_t, shift, top, 0, hist + 1);
        kept += len[s];
    }
    for (uint32_t b = 0; b < buckets; b++)
        hist[b + 1] += hist[b];
    for (int s = 0; s < sources; s++)
        for (size_t k = 0; k < len[s]; k++)
            dst[hist[cand_bucket(src[s][k].t, shift, top)]++] = src[s][k];
    finish_buckets(dst, 0, hist, buckets);
    return kept;
}

/* Below this many pair candidates a step's sort runs on one thread: a team's start costs
 * more. */
#define SIM_SORT_TEAM_MIN 65536
/* Coarse buckets a thread of the team sort (sort_candidates_team). */
#define SIM_SORT_COARSE_PER_THREAD 64

/* sort_candidates on a team of `team` threads, with the same result (the key is total):
 *  1. each source filtered (pairs a wall comes first for dropped) and counted into coarse
 *     buckets, SIM_SORT_COARSE_PER_THREAD a thread, each a run of the fine buckets;
 *  2. every source scattered into dst by coarse bucket (sources side by side, each to the
 *     places the counts give it);
 *  3. the coarse buckets shared out: each sorted into its fine buckets through a buffer of its
 *     own size, then ordered within them (finish_buckets).
 * No step is serial but the prefix sums over coarse buckets and sources. Memory: the counts,
 * and per thread a coarse bucket and its fine histogram. Returns the candidates kept, or
 * (size_t)-1 when memory ran out. */
static size_t sort_candidates_team(sim_cand *const *src, size_t *len, int sources,
                                   const sim_real *restrict wall_t, sim_cand *restrict dst,
                                   size_t n, int team)
{
    const int bits = sort_bits(n);
    const int shift = 52 - bits;
    const int64_t top = (int64_t)1 << bits;
    int cbits = 0;
    while (cbits < bits && ((int64_t)1 << cbits) < (int64_t)SIM_SORT_COARSE_PER_THREAD * team)
        cbits++;
    const int cshift = bits - cbits;
    /* Fine buckets 0 .. 2^bits, so coarse 0 .. 2^cbits (the last holds one fine bucket). */
    const uint32_t coarse = (UINT32_C(1) << cbits) + 1, fine = UINT32_C(1) << cshift;
    uint32_t *count = calloc((size_t)sources * coarse, sizeof *count);
    size_t *start = malloc(((size_t)coarse + 1) * sizeof *start);
    if (!count || !start) {
        free(count);
        free(start);
        return (size_t)-1;
    }
    size_t widest = 0;
    int failed = 0;
#pragma omp parallel num_threads(team)
    {
#pragma omp for schedule(dynamic, 1)
        for (int s = 0; s < sources; s++)
            len[s] = count_source(src[s], len[s], wall_t, shift, top, cshift,
                                  count + (size_t)s * coarse);
#pragma omp single
        {
            size_t at = 0;
            for (uint32_t c = 0; c < coarse; c++) {
                start[c] = at;
                for (int s = 0; s < sources; s++) {
                    const uint32_t m = count[(size_t)s * coarse + c];
                    count[(size_t)s * coarse + c] = (uint32_t)(at - start[c]);
                    at += m;
                }
                widest = at - start[c] > widest ? at - start[c] : widest;
            }
            start[coarse] = at;
        }
#pragma omp for schedule(dynamic, 1)
        for (int s = 0; s < sources; s++) {
            uint32_t *restrict place = count + (size_t)s * coarse;
            const sim_cand *restrict c = src[s];
            for (size_t k = 0; k < len[s]; k++) {
                const uint32_t b = cand_bucket(c[k].t, shift, top) >> cshift;
                dst[start[b] + place[b]++] = c[k];
            }
        }
        sim_cand *tmp = malloc((widest ? widest : 1) * sizeof *tmp);
        uint32_t *hist = malloc(((size_t)fine + 2) * sizeof *hist);
        if (!tmp || !hist) {
#pragma omp atomic write
            failed = 1;
        }
#pragma omp for schedule(dynamic, 1)
        for (uint32_t b = 0; b < coarse; b++) {
            const size_t lo = start[b], m = start[b + 1] - lo;
            if (m < 2 || !tmp || !hist)
                continue;
            const int64_t first = (int64_t)b << cshift;
            memcpy(tmp, dst + lo, m * sizeof *tmp);
            memset(hist, 0, ((size_t)fine + 2) * sizeof *hist);
            for (size_t k = 0; k < m; k++)
                hist[cand_bucket(tmp[k].t, shift, top) - first + 1]++;
            for (uint32_t f = 0; f < fine; f++)
                hist[f + 1] += hist[f];
            for (size_t k = 0; k < m; k++)
                dst[lo + hist[cand_bucket(tmp[k].t, shift, top) - first]++] = tmp[k];
            finish_buckets(dst, lo, hist, b + 1 < coarse ? fine : 1);
        }
        free(tmp);
        free(hist);
    }
    const size_t kept = start[coarse];
    free(count);
    free(start);
    return failed ? (size_t)-1 : kept;
}

int sim_sort_candidates(sim_cand *a, sim_cand *tmp, size_t n)
{
    if (n < 2)
        return 0;
    uint32_t *hist = malloc(sort_hist_len(n) * sizeof *hist);
    if (!hist)
        return -1;
    memcpy(tmp, a, n * sizeof *a);
    sort_candidates(&tmp, &n, 1, NULL, hist, a, n);
    free(hist);
    return 0;
}

size_t sim_merge_candidates(sim_stepper *s, sim_stats *stats)
{
    size_t pairs = 0, walls = 0;
    uint64_t dropped = 0;
    bool failed = false;
    for (int k = 0; k < s->sink.count; k++) {
        sim_cand_buf *b = &s->sink.bufs[k];
        pairs += b->len;
        dropped += b->dropped;
        b->dropped = 0;
        failed |= b->failed;
        stats->pair_tests += b->pair_tests;
        s->writer_pairs[k] += b->pair_tests;
        b->pair_tests = 0;
        s->sources[k] = b->items;
        s->source_len[k] = b->len;
    }
    for (int k = 0; k < s->threads; k++) {
        walls += s->walls[k].len;
        failed |= s->walls[k].failed;
    }
    const size_t hist_len = sort_hist_len(pairs);
    if (hist_len > s->hist_cap) {
        uint32_t *p = realloc(s->hist, hist_len * sizeof *p);
        if (!p)
            return (size_t)-1;
        s->hist = p;
        s->hist_cap = hist_len;
    }
    if (failed || !sim_cand_reserve(&s->merged, &s->merged_cap, pairs) ||
        !sim_cand_reserve(&s->wall_moves, &s->wall_moves_cap, walls) ||
        !sim_cand_reserve(&s->pair_moves, &s->pair_moves_cap, pairs))
        return (size_t)-1;
    const size_t kept =
        s->parallel && pairs >= SIM_SORT_TEAM_MIN
            ? sort_candidates_team(s->sources, s->source_len, s->sink.count, s->wall_t,
                                   s->merged, pairs, s->threads)
            : sort_candidates(s->sources, s->source_len, s->sink.count, s->wall_t, s->hist,
                              s->merged, pairs);
    if (kept == (size_t)-1)
        return kept;
    for (int k = 0; k < s->sink.count; k++)
        s->sink.bufs[k].len = 0;
    stats->candidates += pairs + walls + dropped;
    return kept;
}
