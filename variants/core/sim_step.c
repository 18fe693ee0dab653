/*
 * sim_step.c: one step of SPEC §2, shared by every variant.
 *
 *   1. wall candidates (one buffer per thread, in particle order, and every particle's wall
 *      time in wall_t; found by the wall pass at the end of the step before, or here for a
 *      first step) and pair candidates (the variant's finder, into per-writer buffers);
 *   2. the pairs sorted by the total key (t, i, j);
 *   3. the greedy walk over all candidates in key order (t, pair before wall, i, j), accepting
 *      a candidate when neither particle has been accepted yet, done as a walk over the sorted
 *      pairs that knows each particle's wall time, then a pass over the walls (resolve says
 *      why that is the same walk);
 *   4. every particle moves exactly once, reading the old state and writing a new one, so the
 *      motion can run in parallel without races and with thread-independent results: all by
 *      their velocity, then the accepted collisions over their own particles (sim_motion.c);
 *      the new state's wall candidates are found right after, in the same region.
 * Issue 15 made 2-4 cheap (about 60 -> 17 ns per particle-step outside the broad phase on the
 * report benchmark, input and output included): no branch on a random outcome in a loop over
 * particles or candidates, vectorised passes over particles, streams instead of scattered
 * accesses to cold memory.
 *
 * Why per-writer buffers and not the seed's shared array behind `omp critical`: the critical
 * section serialised every candidate append (the report's bottleneck), and the order in which
 * threads entered it was the order candidates were found, which is not reproducible. Private
 * buffers need no lock; the sort makes the order irrelevant.
 */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include <omp.h>

#include "sim_core.h"

/* Below this many particles the per-particle loops (wall times, motion) are not worth a
 * parallel region (see team_pays). */
#define SIM_PARALLEL_MIN 4096

/* Bytes per cache line, for prefetching a whole array. */
#define SIM_CACHE_LINE 64

/* Steps after which the byte counts of collisions are added to the world's (a particle has
 * at most one collision a step, so a byte holds this many). */
#define SIM_COUNT_FLUSH 255

/* Particles per block of the wall pass and of the motion's pass over every particle: the
 * wall pass's distances stay in stack arrays (L1) between its vectorised loops. */
#define SIM_WALL_BLOCK 256

struct sim_stepper {
    const sim_variant *variant;
    int threads;
    bool parallel;
    sim_pair_sink sink;
    sim_cand_buf *walls; /* the wall candidates of the world's state, one buffer per thread */
    bool walls_ready;    /* walls were found by the last step's wall pass (see sim_step) */
    sim_cand *merged; /* this step's pair candidates that a wall does not come first for, sorted */
    size_t merged_cap;
    uint32_t *hist; /* the sort's histogram (sort_candidates) */
    size_t hist_cap;
    /* The finder's candidate buffers as the sort reads them. */
    sim_cand **sources;
    size_t *source_len;
    /* The candidates the greedy walk accepted, walls and pairs apart, in walk order. */
    sim_cand *wall_moves, *pair_moves;
    size_t wall_moves_cap, pair_moves_cap, wall_moves_len, pair_moves_len;
    /* The accepted pairs' new states, SIM_PAIR_OUT reals each, where a team moves them (see
     * sim_step). */
    sim_real *pair_out;
    size_t pair_out_cap; /* in pairs */
    unsigned char *taken; /* n + 1 flags, all 0 between walks (see resolve) */
    sim_real *wall_t;     /* each particle's wall time in the world's state (see resolve) */
    /* Collisions of each kind per particle not yet added to the world's pcoll / wcoll (see
     * move_free), added every SIM_COUNT_FLUSH steps and by sim_stepper_destroy. */
    unsigned char *pair_count, *wall_count;
    int64_t *pcoll, *wcoll; /* the world's counts they are added to */
    int32_t n;
    int unflushed; /* steps counted since the last flush */
    /* The next positions, swapped with the world's arrays. Velocities change in place: only
     * the moves of accepted collisions change them, each its own particles' (sim_motion.c). */
    sim_real *nx, *ny;
    uint64_t *writer_pairs;        /* pair tests per candidate buffer over the run */
};

/* Time for a centre at q moving at w to reach the wall ahead (SPEC §2); infinite when w == 0. */
static inline sim_real axis_time(sim_real q, sim_real w, sim_real lo, sim_real hi)
{
    if (w > 0)
        return (hi - q) / w;
    if (w < 0)
        return (lo - q) / w;
    return SIM_REAL_INF;
}

static inline sim_real clamp(sim_real q, sim_real lo, sim_real hi)
{
    return q < lo ? lo : (q > hi ? hi : q);
}

/* SPEC §2 wall time of a centre at (x, y) moving at (vx, vy). */
static inline sim_real wall_time(sim_real x, sim_real y, sim_real vx, sim_real vy, sim_real lo,
                                 sim_real hi)
{
    const sim_real tx = axis_time(x, vx, lo, hi), ty = axis_time(y, vy, lo, hi);
    return tx < ty ? tx : ty;
}

sim_real sim_wall_time(const sim_world *w, int32_t i)
{
    return wall_time(w->x[i], w->y[i], w->vx[i], w->vy[i], w->lo, w->hi);
}

sim_real sim_stepper_wall_time(const sim_stepper *s, int32_t i)
{
    return s->wall_t[i];
}

static bool buf_reserve(sim_cand **items, size_t *cap, size_t need)
{
    if (need <= *cap)
        return true;
    size_t c = *cap ? *cap : 1;
    while (c < need)
        c *= 2;
    sim_cand *p = realloc(*items, c * sizeof *p);
    if (!p)
        return false;
    *items = p;
    *cap = c;
    return true;
}

sim_stepper *sim_stepper_create(const sim_world *w, const sim_variant *v, int threads)
{
    sim_stepper *s = calloc(1, sizeof *s);
    if (!s)
        return NULL;
    s->variant = v;
    s->threads = v->parallel ? threads : 1;
    s->parallel = v->parallel && threads > 1;
    int count = v->buffer_count ? v->buffer_count(s->threads) : s->threads;
    if (count < 1)
        count = 1;
    s->sink.count = count;
    s->sink.threads = s->threads;
    /* sizeof(sim_cand_buf) is a multiple of its 64-byte alignment, as aligned_alloc needs. */
    s->sink.bufs = aligned_alloc(_Alignof(sim_cand_buf), (size_t)count * sizeof(sim_cand_buf));
    s->walls = aligned_alloc(_Alignof(sim_cand_buf), (size_t)s->threads * sizeof(sim_cand_buf));
    const size_t n = (size_t)w->n;
    s->taken = calloc(n + 1, 1);
    s->wall_t = malloc((n + 1) * sizeof *s->wall_t);
    s->pair_count = calloc(n + 1, 1);
    s->wall_count = calloc(n + 1, 1);
    s->pcoll = w->pcoll;
    s->wcoll = w->wcoll;
    s->n = w->n;
    s->nx = malloc(n * sizeof(sim_real) + 1);
    s->ny = malloc(n * sizeof(sim_real) + 1);
    s->writer_pairs = calloc((size_t)count, sizeof *s->writer_pairs);
    s->sources = malloc((size_t)count * sizeof *s->sources);
    s->source_len = malloc((size_t)count * sizeof *s->source_len);
    if (!s->sink.bufs || !s->walls || !s->taken || !s->wall_t || !s->pair_count ||
        !s->wall_count || !s->nx || !s->ny ||
        !s->writer_pairs || !s->sources || !s->source_len) {
        sim_stepper_destroy(s);
        return NULL;
    }
    memset(s->sink.bufs, 0, (size_t)count * sizeof(sim_cand_buf));
    memset(s->walls, 0, (size_t)s->threads * sizeof(sim_cand_buf));
    if (s->parallel)
        sim_team_spread(s->threads);
    if (v->scratch_create) {
        s->sink.scratch = v->scratch_create(w, s->threads);
        if (!s->sink.scratch) {
            sim_stepper_destroy(s);
            return NULL;
        }
    }
    return s;
}

/* Whether the per-particle loops of a world of n particles (wall times, motion) run on the
 * stepper's team: the one home of the SIM_PARALLEL_MIN rule. */
static bool team_pays(const sim_stepper *s, int32_t n)
{
    return s->parallel && n >= SIM_PARALLEL_MIN;
}

/* Add the counts of the steps since the last flush to the world's pcoll and wcoll. */
static void flush_counts(sim_stepper *s)
{
    if (!s->pair_count || !s->wall_count)
        return;
    for (int32_t i = 0; i < s->n; i++) {
        s->pcoll[i] += s->pair_count[i];
        s->wcoll[i] += s->wall_count[i];
        s->pair_count[i] = s->wall_count[i] = 0;
    }
    s->unflushed = 0;
}

void sim_stepper_destroy(sim_stepper *s)
{
    if (!s)
        return;
    flush_counts(s);
    if (s->sink.scratch && s->variant->scratch_destroy)
        s->variant->scratch_destroy(s->sink.scratch);
    if (s->sink.bufs)
        for (int k = 0; k < s->sink.count; k++)
            free(s->sink.bufs[k].items);
    free(s->sink.bufs);
    if (s->walls)
        for (int k = 0; k < s->threads; k++)
            free(s->walls[k].items);
    free(s->walls);
    free(s->merged);
    free(s->hist);
    free(s->sources);
    free(s->source_len);
    free(s->wall_moves);
    free(s->pair_out);
    free(s->pair_moves);
    free(s->taken);
    free(s->wall_t);
    free(s->pair_count);
    free(s->wall_count);
    free(s->nx);
    free(s->ny);
    free(s->writer_pairs);
    free(s);
}

int sim_stepper_writers(const sim_stepper *s)
{
    return s->sink.count;
}

sim_thread_work sim_stepper_work(const sim_stepper *s, int k)
{
    return (sim_thread_work){.busy_s = s->sink.bufs[k].busy_s,
                             .pairs = s->writer_pairs[k],
                             .chunks = s->sink.bufs[k].chunks};
}

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
 * an eighth of the candidates' own size. The fixed 2^13 buckets this replaced left a million
 * particles' 1.8 million pair candidates a step about 220 to a bucket, each sorted by qsort:
 * sort_s 1.66 s of the million's 10 steps (`1000000 200000 1 10`, 2 threads), 0.44 s now,
 * with the drop below. */
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

/* Sort the candidates of src[0..sources) (src[s] holding len[s], n in all) into dst by
 * cand_cmp, and return how many there are in dst: a counting sort into about n/2 buckets of t
 * (stable, O(n): a step's few thousand candidates took 0.6 ms in qsort's merge sort, and 43 us
 * in the two passes of the 11-bit radix sort this replaced), straight from the writers'
 * buffers, then cand_cmp within the buckets, which are short (finish_long_bucket takes the rest).
 * Where wall_t is not NULL the sources are pairs, and the pass that counts them first drops
 * every pair that a wall of one of its particles comes before (wall_t[i] or wall_t[j] < t:
 * at equal times the pair comes first), compacting each source in place and shortening
 * len[s]: the greedy walk would refuse it (resolve says why) and it changes nothing else, and
 * the sort, the walk and the motion then see only the pairs that can be accepted (about a
 * sixth of the million particles' pairs after the first step, a twentieth of the report
 * benchmark's). hist holds sort_hist_len(n) entries. */
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
        sim_cand *restrict c = src[s];
        const size_t m = len[s];
        if (!wall_t) {
            for (size_t k = 0; k < m; k++)
                hist[cand_bucket(c[k].t, shift, top) + 1]++;
            kept += m;
            continue;
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
            hist[cand_bucket(e.t, shift, top) + 1] += keep;
        }
        len[s] = out;
        kept += out;
    }
    for (uint32_t b = 0; b < buckets; b++)
        hist[b + 1] += hist[b];
    for (int s = 0; s < sources; s++)
        for (size_t k = 0; k < len[s]; k++)
            dst[hist[cand_bucket(src[s][k].t, shift, top)]++] = src[s][k];
    /* Long buckets first (rare: see finish_long_bucket), then one insertion pass over the
     * whole list: buckets hold a few candidates, and an insertion never crosses into an
     * earlier bucket (its times are all smaller), so the pass costs one comparison a
     * candidate and a move per pair out of order. */
    for (uint32_t b = 0; b < buckets; b++) {
        const uint32_t lo = b ? hist[b - 1] : 0;
        if (hist[b] - lo > SIM_INSERTION_MAX)
            finish_long_bucket(dst, lo, hist[b]);
    }
    for (size_t k = 1; k < kept; k++) {
        if (!cand_before(&dst[k], &dst[k - 1]))
            continue;
        const sim_cand c = dst[k];
        size_t m = k;
        do {
            dst[m] = dst[m - 1];
            m--;
        } while (m > 0 && cand_before(&c, &dst[m - 1]));
        dst[m] = c;
    }
    return kept;
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

static void clear_walls(sim_stepper *s)
{
    for (int k = 0; k < s->threads; k++)
        s->walls[k].len = 0;
}

/* Append the wall candidates of particles [i0, i1) of the state (x, y, vx, vy) to buf, in
 * increasing i, and write every particle's wall time to wall_t. Blocks of SIM_WALL_BLOCK, in
 * three passes that each vectorise or need no branch (a fifth of the particles on the report
 * benchmark are candidates, at random: a branch on it mispredicts):
 *  1. the distance to the wall ahead on each axis (the wall is hi when w > 0, else lo);
 *  2. the axis times, the same IEEE operations as axis_time where w != 0, infinity where
 *     w == 0 (the division by 0 is computed and discarded), and their minimum, into wall_t.
 *     Passes 1 and 2 as one loop GCC 12 does not vectorise: jump threading turns the two
 *     selects on w into branches;
 *  3. an append that writes every particle and advances only past candidates. */
static void find_walls_range(sim_cand_buf *buf, sim_real *restrict wall_t,
                             const sim_real *restrict x, const sim_real *restrict y,
                             const sim_real *restrict vx, const sim_real *restrict vy,
                             sim_real lo, sim_real hi, int32_t i0, int32_t i1)
{
    sim_real ax[SIM_WALL_BLOCK], ay[SIM_WALL_BLOCK];
    for (int32_t b = i0; b < i1; b += SIM_WALL_BLOCK) {
        const int32_t len = i1 - b < SIM_WALL_BLOCK ? i1 - b : SIM_WALL_BLOCK;
        const sim_real *restrict xb = x + b, *restrict yb = y + b;
        const sim_real *restrict vxb = vx + b, *restrict vyb = vy + b;
        sim_real *restrict tw = wall_t + b;
        for (int32_t k = 0; k < len; k++) {
            ax[k] = (vxb[k] > 0 ? hi : lo) - xb[k];
            ay[k] = (vyb[k] > 0 ? hi : lo) - yb[k];
        }
        for (int32_t k = 0; k < len; k++) {
            const sim_real tx = ax[k] / vxb[k], ty = ay[k] / vyb[k];
            const sim_real txw = vxb[k] != 0 ? tx : SIM_REAL_INF;
            const sim_real tyw = vyb[k] != 0 ? ty : SIM_REAL_INF;
            tw[k] = txw < tyw ? txw : tyw;
        }
        if (!buf_reserve(&buf->items, &buf->cap, buf->len + (size_t)len)) {
            buf->failed = true;
            return;
        }
        sim_cand *items = buf->items;
        size_t at = buf->len;
        for (int32_t k = 0; k < len; k++) {
            items[at] = (sim_cand){.t = tw[k], .i = b + k, .j = SIM_WALL};
            at += tw[k] <= 1;
        }
        buf->len = at;
    }
}

/* Thread `me` of `team`'s share of [0, blocks): [*b0, *b1), contiguous and in thread order, so
 * that each thread's wall buffer holds a run of particles and the buffers follow each other
 * in particle order. */
static void share(int32_t blocks, int me, int team, int32_t *b0, int32_t *b1)
{
    *b0 = (int32_t)((int64_t)blocks * me / team);
    *b1 = (int32_t)((int64_t)blocks * (me + 1) / team);
}

/* Particles [i0, i1) of the block range [b0, b1) of n particles. */
static void block_span(int32_t n, int32_t b0, int32_t b1, int32_t *i0, int32_t *i1)
{
    *i0 = b0 * SIM_WALL_BLOCK;
    *i1 = (int64_t)b1 * SIM_WALL_BLOCK < n ? b1 * SIM_WALL_BLOCK : n;
    if (*i0 > *i1)
        *i0 = *i1;
}

/* The wall candidates of the world's state, for a first step, each thread for its share;
 * later steps get them from the wall pass at the end of the step before. */
static void find_walls(sim_stepper *s, const sim_world *w)
{
    clear_walls(s);
    const int32_t blocks = (w->n + SIM_WALL_BLOCK - 1) / SIM_WALL_BLOCK;
#pragma omp parallel num_threads(s->threads) if (team_pays(s, w->n))
    {
        const int me = omp_get_thread_num();
        int32_t b0, b1, i0, i1;
        share(blocks, me, omp_get_num_threads(), &b0, &b1);
        block_span(w->n, b0, b1, &i0, &i1);
        find_walls_range(&s->walls[me], s->wall_t, w->x, w->y, w->vx, w->vy, w->lo, w->hi, i0,
                         i1);
    }
}

/* Sort the finder's pair candidates into one list, less those a wall comes first for (the
 * walls need no sorting: see resolve). Returns the number of pairs in it, or (size_t)-1 when
 * memory ran out. */
static size_t merge_candidates(sim_stepper *s, sim_stats *stats)
{
    size_t pairs = 0, walls = 0;
    bool failed = false;
    for (int k = 0; k < s->sink.count; k++) {
        sim_cand_buf *b = &s->sink.bufs[k];
        pairs += b->len;
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
    if (failed || !buf_reserve(&s->merged, &s->merged_cap, pairs) ||
        !buf_reserve(&s->wall_moves, &s->wall_moves_cap, walls) ||
        !buf_reserve(&s->pair_moves, &s->pair_moves_cap, pairs))
        return (size_t)-1;
    const size_t kept = sort_candidates(s->sources, s->source_len, s->sink.count, s->wall_t,
                                        s->hist, s->merged, pairs);
    for (int k = 0; k < s->sink.count; k++)
        s->sink.bufs[k].len = 0;
    stats->candidates += pairs + walls;
    return kept;
}

/* taken[i] after the greedy walk: the kind of particle i's accepted collision, if any. */
#define SIM_TAKEN_PAIR 1
#define SIM_TAKEN_WALL 2

/* SPEC §2's greedy walk over all candidates in key order (t; pair before wall; i; j), accepting
 * a candidate when neither of its particles is taken yet, done without sorting the walls:
 *  1. the pairs, in key order: particle a is taken when an accepted pair took it, or when its
 *     wall candidate comes first (wall_t[a] < t: at equal times the pair comes first). That
 *     wall was accepted then, unless a pair took a before it, and then a is taken anyway; a
 *     wall time above 1 (no candidate) never comes first. Such a pair is refused and changes
 *     nothing, so the sort dropped it already (sort_candidates): here a pair is accepted when
 *     no accepted pair took either particle;
 *  2. the walls, in particle order: a wall is accepted when no accepted pair took its particle
 *     (a pair after the wall that takes its particle would have been refused in 1).
 * Branch-free (what is accepted, and which particles are free, is random: branches on it
 * mispredicted): every candidate is written to its list of accepted moves, which advances only
 * past accepted ones. The flags are counted and cleared by the motion's pass over every
 * particle (move_free). */
static void resolve(sim_stepper *s, size_t count, sim_stats *stats)
{
    unsigned char *restrict taken = s->taken;
    const sim_cand *restrict cand = s->merged;
    sim_cand *restrict pairs = s->pair_moves, *restrict walls = s->wall_moves;
    size_t np = 0, nw = 0;
    for (size_t k = 0; k < count; k++) {
        const sim_cand c = cand[k];
        const unsigned ok = !(taken[c.i] | taken[c.j]);
        taken[c.i] |= (unsigned char)(ok * SIM_TAKEN_PAIR);
        taken[c.j] |= (unsigned char)(ok * SIM_TAKEN_PAIR);
        pairs[np] = c;
        np += ok;
    }
    for (int b = 0; b < s->threads; b++) {
        const sim_cand *restrict wall = s->walls[b].items;
        for (size_t k = 0; k < s->walls[b].len; k++) {
            const sim_cand c = wall[k];
            const unsigned ok = !taken[c.i];
            taken[c.i] |= (unsigned char)(ok * SIM_TAKEN_WALL);
            walls[nw] = c;
            nw += ok;
        }
    }
    s->wall_moves_len = nw;
    s->pair_moves_len = np;
    stats->wall_collisions += nw;
    stats->pair_collisions += np;
}

/* Particles [0, len) of the given arrays move by their whole velocity (no collision), from
 * the world's positions into the next ones; the collisions the walk accepted are counted and
 * their flags cleared for the next walk. The counts go into bytes, added to the world's
 * 64-bit pcoll and wcoll every SIM_COUNT_FLUSH steps: an increment per event missed the cache
 * (nothing else in a step touches the counts), and a 64-bit add per particle and step
 * streamed 32 bytes (0.5 ms of the report benchmark's 50 steps). A function of its own so
 * that GCC sees restrict pointers (in the parallel region they are loads from the region's
 * shared data) and vectorises. */
static void move_free(sim_real *restrict nx, sim_real *restrict ny, const sim_real *restrict x,
                      const sim_real *restrict y, const sim_real *restrict vx,
                      const sim_real *restrict vy, unsigned char *restrict pair_count,
                      unsigned char *restrict wall_count, unsigned char *restrict taken,
                      int32_t len, sim_real lo, sim_real hi)
{
    for (int32_t i = 0; i < len; i++) {
        nx[i] = clamp(x[i] + vx[i], lo, hi);
        ny[i] = clamp(y[i] + vy[i], lo, hi);
    }
    for (int32_t i = 0; i < len; i++) {
        pair_count[i] += taken[i] & SIM_TAKEN_PAIR;
        wall_count[i] += taken[i] >> 1;
        taken[i] = 0;
    }
}

static void swap_arrays(sim_real **a, sim_real **b)
{
    sim_real *t = *a;
    *a = *b;
    *b = t;
}

int sim_step(sim_stepper *s, sim_world *w, sim_stats *stats)
{
    const int32_t n = w->n;
    double t0 = omp_get_wtime(), t1;
    if (!s->walls_ready) {
        find_walls(s, w);
        t1 = omp_get_wtime();
        stats->walls_s += t1 - t0;
        t0 = t1;
    }
    s->walls_ready = false;
    s->variant->find_pairs(w, &s->sink);
    t1 = omp_get_wtime();
    stats->broad_s += t1 - t0;
    const size_t count = merge_candidates(s, stats);
    if (count == (size_t)-1)
        return -1;
    t0 = omp_get_wtime();
    stats->sort_s += t0 - t1;
    resolve(s, count, stats);
    t1 = omp_get_wtime();
    stats->resolve_s += t1 - t0;
    /* Motion, then the next step's wall candidates, in one parallel region with one barrier
     * (on a loaded machine a barrier can wait a scheduler tick for a descheduled thread):
     *  1. each thread for its own run of particles (share): all move by their velocity into
     *     the next positions (vectorised; most have no collision: 55% on the report
     *     benchmark), which also brings the old state into the caches for 2;
     *  2. the accepted pairs' new states, into pair_out (reading the old state only), shared
     *     out by blocks of pairs; the barrier;
     *  3. each thread for its own particles: the accepted walls move (the wall list is in
     *     particle order), the pair states are copied from pair_out;
     *  4. the same thread, the wall candidates of its particles' new state.
     * Before the barrier nothing writes the old state; after it a thread writes only its own
     * particles and reads nothing another wrote after the barrier, so 3 and 4 need none.
     * Timed on thread 0, the thread that calls sim_step: motion_s from the region's start to
     * the end of its 3 (the barrier included), walls_s its 4; the region's start-up before
     * thread 0 runs and the closing barrier are in neither, but in sim_s. One thread takes
     * the same steps without a region (below), the pairs written straight into the next
     * state. */
    clear_walls(s);
    double motion_s = 0, walls_s = 0;
    const sim_real lo = w->lo, hi = w->hi;
    const size_t nw = s->wall_moves_len, np = s->pair_moves_len, eb = sim_event_block();
    const int32_t blocks = (n + SIM_WALL_BLOCK - 1) / SIM_WALL_BLOCK;
    const int32_t pair_blocks = (int32_t)((np + eb - 1) / eb);
    const sim_cand *wall_moves = s->wall_moves, *pair_moves = s->pair_moves;
    if (!team_pays(s, n)) {
        /* One thread: the same moves in the same order with no barrier to spare, the pairs
         * written straight into the next state (the copy through pair_out cost 1 ms of the
         * report benchmark). */
        const double m0 = omp_get_wtime();
        for (int32_t b = 0; b < blocks; b++) {
            int32_t j0, j1;
            block_span(n, b, b + 1, &j0, &j1);
            move_free(s->nx + j0, s->ny + j0, w->x + j0, w->y + j0, w->vx + j0, w->vy + j0,
                      s->pair_count + j0, s->wall_count + j0, s->taken + j0, j1 - j0, lo, hi);
        }
        for (size_t k = 0; k < nw; k += eb)
            sim_move_walls(w, wall_moves, nw, k, s->nx, s->ny);
        for (size_t k = 0; k < np; k += eb)
            sim_move_pairs(w, pair_moves, np, k, NULL, s->nx, s->ny);
        const double m1 = omp_get_wtime();
        find_walls_range(&s->walls[0], s->wall_t, s->nx, s->ny, w->vx, w->vy, lo, hi, 0, n);
        motion_s = m1 - m0;
        walls_s = omp_get_wtime() - m1;
    } else {
        if (np > s->pair_out_cap) {
            sim_real *p = realloc(s->pair_out, np * SIM_PAIR_OUT * sizeof *p);
            if (!p)
                return -1;
            s->pair_out = p;
            s->pair_out_cap = np;
        }
#pragma omp parallel num_threads(s->threads)
        {
            const int me = omp_get_thread_num();
            const double m0 = me == 0 ? omp_get_wtime() : 0;
            int32_t b0, b1, i0, i1;
            share(blocks, me, omp_get_num_threads(), &b0, &b1);
            block_span(n, b0, b1, &i0, &i1);
            for (int32_t b = b0; b < b1; b++) {
                int32_t j0, j1;
                block_span(n, b, b + 1, &j0, &j1);
                move_free(s->nx + j0, s->ny + j0, w->x + j0, w->y + j0, w->vx + j0, w->vy + j0,
                          s->pair_count + j0, s->wall_count + j0, s->taken + j0, j1 - j0, lo, hi);
            }
#pragma omp for schedule(static)
            for (int32_t b = 0; b < pair_blocks; b++)
                sim_move_pairs(w, pair_moves, np, (size_t)b * eb, s->pair_out, NULL, NULL);
            /* My walls: the run of the particle-ordered list with i in [i0, i1). */
            size_t k0 = 0, k1 = nw;
            while (k0 < k1) { /* first k with i >= i0 */
                const size_t mid = k0 + (k1 - k0) / 2;
                if (wall_moves[mid].i < i0)
                    k0 = mid + 1;
                else
                    k1 = mid;
            }
            for (k1 = k0; k1 < nw && wall_moves[k1].i < i1;)
                k1++;
            for (size_t k = k0; k < k1; k += eb)
                sim_move_walls(w, wall_moves, k1, k, s->nx, s->ny);
            for (size_t k = 0; k < np; k++)
                for (int side = 0; side < 2; side++) {
                    const int32_t i = side ? pair_moves[k].j : pair_moves[k].i;
                    if (i < i0 || i >= i1)
                        continue;
                    const sim_real *o = s->pair_out + SIM_PAIR_OUT * k + 4 * side;
                    s->nx[i] = o[0];
                    s->ny[i] = o[1];
                    w->vx[i] = o[2];
                    w->vy[i] = o[3];
                }
            const double m1 = me == 0 ? omp_get_wtime() : 0;
            find_walls_range(&s->walls[me], s->wall_t, s->nx, s->ny, w->vx, w->vy, lo, hi, i0,
                             i1);
            if (me == 0) {
                motion_s = m1 - m0;
                walls_s = omp_get_wtime() - m1;
            }
        }
    }
    stats->motion_s += motion_s;
    stats->walls_s += walls_s;
    swap_arrays(&w->x, &s->nx);
    swap_arrays(&w->y, &s->ny);
    s->walls_ready = true;
    if (++s->unflushed == SIM_COUNT_FLUSH)
        flush_counts(s);
    return 0;
}
