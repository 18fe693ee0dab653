#!/usr/bin/env bash
# manycore.sh BASE_DIR [NEW_DIR]: grid's thread scaling, memory and phases, two builds compared
# in one session, runs interleaved (base, new, base, new ...), on a bare many-core machine:
# bash, gcc and make only (no Python, no hyperfine, no /usr/bin/time).
#
#   scripts/manycore.sh /path/to/main/build build    # BASE_DIR, NEW_DIR hold grid and p1d
#   OUT=results/manycore-host scripts/manycore.sh ...   # keep every raw number there too
#   MANYCORE_SMALL=1 scripts/manycore.sh ...            # small scenes: a check of the script
#
# It first runs `make -j all` in this checkout (NEW_DIR defaults to its build/), then measures:
#   1. grid, n=10000 L=20000 r=1 S=50 (the report benchmark), threads 1 2 4 8 16, 5 runs each:
#      median and fastest wall time;
#   2. grid, n=1e6 L=2e5 r=1 S=10, threads 1 4 8 16, 2 runs each;
#   3. grid's peak RSS, n=1e6 S=2, threads 1 2 4 8 16 (getrusage of the child, a C helper);
#   4. p1d, n=10000 S=50 at 1 and 16 threads: a control of the machine's scaling;
#   5. grid --timing at 16 threads on 1 and 2, and at 1 thread on 1 (the phases, each thread's
#      busy time and pair tests, and the run's CPU time, page faults and context switches).
# Wall times are the run's own (date +%s.%N around it), output to /dev/null. About 4-5 minutes
# on 16 cores. Prints a compact table; with OUT set, writes runs.csv, rss.csv, timing.jsonl
# and table.txt there as well.
set -euo pipefail

BASE=${1:?usage: manycore.sh BASE_DIR [NEW_DIR]}
ROOT=$(cd "$(dirname "$0")/.." && pwd)
NEW=${2:-$ROOT/build}
BASE=$(cd "$BASE" && pwd)

make -C "$ROOT" -j "$(nproc)" all >/dev/null
NEW=$(cd "$NEW" && pwd)
for d in "$BASE" "$NEW"; do
    for v in grid p1d; do
        [[ -x "$d/$v" ]] || { echo "manycore.sh: missing $d/$v" >&2; exit 2; }
    done
done

TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
OUTDIR=${OUT:-$TMP/out}
mkdir -p "$OUTDIR"

# What a child process used (its rusage), written to stderr's last line: peak RSS (KiB), user
# and system CPU seconds, minor page faults (first touches of memory: per-thread scratch shows
# here), voluntary and involuntary context switches (threads waiting, threads preempted).
cat >"$TMP/peakrss.c" <<'C'
#include <stdio.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>
int main(int argc, char **argv)
{
    if (argc < 2)
        return 2;
    pid_t p = fork();
    if (p == 0) {
        execvp(argv[1], argv + 1);
        _exit(127);
    }
    int st;
    struct rusage ru;
    if (wait4(p, &st, 0, &ru) < 0)
        return 1;
    fprintf(stderr, "peak_rss_kb %ld user_s %.3f sys_s %.3f minflt %ld nvcsw %ld nivcsw %ld\n",
            ru.ru_maxrss, ru.ru_utime.tv_sec + ru.ru_utime.tv_usec / 1e6,
            ru.ru_stime.tv_sec + ru.ru_stime.tv_usec / 1e6, ru.ru_minflt, ru.ru_nvcsw,
            ru.ru_nivcsw);
    return WIFEXITED(st) ? WEXITSTATUS(st) : 1;
}
C
gcc -O2 -o "$TMP/peakrss" "$TMP/peakrss.c"

if [[ -n "${MANYCORE_SMALL:-}" ]]; then
    SMALL_SCENE="2000 4000 1 10"; BIG_SCENE="20000 28284.27 1 2"; RSS_SCENE="20000 28284.27 1 1"
    SMALL_THREADS="1 2 4"; BIG_THREADS="1 2"; RSS_THREADS="1 2 4"; CONTROL_THREADS="1 2"
    SMALL_REPS=3; BIG_REPS=2; CONTROL_REPS=2
else
    SMALL_SCENE="10000 20000 1 50"; BIG_SCENE="1000000 200000 1 10"; RSS_SCENE="1000000 200000 1 2"
    SMALL_THREADS="1 2 4 8 16"; BIG_THREADS="1 4 8 16"; RSS_THREADS="1 2 4 8 16"
    CONTROL_THREADS="1 16"
    SMALL_REPS=5; BIG_REPS=2; CONTROL_REPS=3
fi
scene() { printf '%s\nperf\n' "$1" >"$TMP/$2.in"; }
scene "$SMALL_SCENE" small
scene "$BIG_SCENE" big
scene "$RSS_SCENE" rss

echo "case,build,threads,rep,seconds" >"$OUTDIR/runs.csv"
echo "build,threads,peak_rss_kb,user_s,sys_s,minflt,nvcsw,nivcsw" >"$OUTDIR/rss.csv"
: >"$OUTDIR/timing.jsonl"

# wall BIN ARGS...: the run's wall time in seconds; a failed run stops the script.
wall() {
    local t0 t1
    t0=$(date +%s.%N)
    "$@" >/dev/null || { echo "manycore.sh: failed: $*" >&2; exit 1; }
    t1=$(date +%s.%N)
    awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.4f\n", b - a }'
}

# timed CASE VARIANT SCENE THREADS REPS: REPS rounds of base then new.
timed() {
    local name=$1 v=$2 sc=$3 t=$4 reps=$5 rep build dir s
    for ((rep = 1; rep <= reps; rep++)); do
        for build in base new; do
            dir=$BASE; [[ $build == new ]] && dir=$NEW
            s=$(wall "$dir/$v" --threads "$t" "$TMP/$sc.in")
            echo "$name,$build,$t,$rep,$s" >>"$OUTDIR/runs.csv"
        done
        echo -n "." >&2
    done
}

echo "grid $SMALL_SCENE" >&2
for t in $SMALL_THREADS; do timed grid_small grid small "$t" "$SMALL_REPS"; done
echo >&2; echo "p1d $SMALL_SCENE (control)" >&2
for t in $CONTROL_THREADS; do timed p1d_small p1d small "$t" "$CONTROL_REPS"; done
echo >&2; echo "grid $BIG_SCENE" >&2
for t in $BIG_THREADS; do timed grid_big grid big "$t" "$BIG_REPS"; done
echo >&2; echo "peak RSS, grid $RSS_SCENE" >&2
for t in $RSS_THREADS; do
    for build in base new; do
        dir=$BASE; [[ $build == new ]] && dir=$NEW
        use=$("$TMP/peakrss" "$dir/grid" --threads "$t" "$TMP/rss.in" 2>&1 >/dev/null |
            awk '/^peak_rss_kb/ { print $2 "," $4 "," $6 "," $8 "," $10 "," $12 }')
        echo "$build,$t,$use" >>"$OUTDIR/rss.csv"
    done
    echo -n "." >&2
done
echo >&2
# --timing's JSON line with the run's rusage in front: a thread's pair tests per busy second at 1
# and at 16 threads, and what the threads cost the kernel (faults, switches) around them.
timing() {
    local sc=$1 t=$2 build=$3 dir=$4
    "$TMP/peakrss" "$dir/grid" --threads "$t" --timing "$TMP/$sc.in" 2>&1 >/dev/null | awk \
        -v head="{\"scene\": \"$sc\", \"build_dir\": \"$build\", " '
        /^\{/ { json = substr($0, 2) }
        /^peak_rss_kb/ { use = sprintf("\"peak_rss_kb\": %s, \"user_s\": %s, \"sys_s\": %s, \"minflt\": %s, \"nvcsw\": %s, \"nivcsw\": %s, ", $2, $4, $6, $8, $10, $12) }
        END { print head use json }' >>"$OUTDIR/timing.jsonl"
}
for build in base new; do
    dir=$BASE; [[ $build == new ]] && dir=$NEW
    timing small 1 "$build" "$dir"
    for sc in small big; do timing "$sc" 16 "$build" "$dir"; done
done

# The table: median and fastest per case, build and thread count; new / base of the medians.
{
    echo "machine: $(nproc) CPUs, $(uname -r); base $BASE; new $NEW"
    echo "case            threads  base median   base min  new median    new min  new/base"
    awk -F, 'NR > 1 { k = $1 "," $3; v[k, $2] = v[k, $2] " " $5; keys[k] = 1 }
        function stats(list, out,   a, n, i, j, t) {
            n = split(list, a, " ");
            for (i = 1; i <= n; i++) for (j = i + 1; j <= n; j++) if (a[j] + 0 < a[i] + 0) { t = a[i]; a[i] = a[j]; a[j] = t }
            out["min"] = a[1]; out["med"] = n % 2 ? a[(n + 1) / 2] : (a[n / 2] + a[n / 2 + 1]) / 2
        }
        END {
            for (k in keys) {
                split(k, p, ","); stats(v[k, "base"], b); stats(v[k, "new"], m)
                printf "%-15s %7d %11.4f %10.4f %11.4f %10.4f %9.3f\n", p[1], p[2], b["med"], b["min"], m["med"], m["min"], m["med"] / b["med"]
            }
        }' "$OUTDIR/runs.csv" | sort -k1,1 -k2,2n
    echo
    echo "peak RSS (MiB), minor page faults and involuntary context switches, grid $RSS_SCENE"
    awk -F, 'NR > 1 { r[$2, $1] = $3; f[$2, $1] = $6; c[$2, $1] = $8; t[$2] = 1 }
        END { printf "threads  base MiB   new MiB  base minflt  new minflt  base nivcsw  new nivcsw\n";
              for (x in t) printf "%7d %9.1f %9.1f %12d %11d %12d %11d\n", x, r[x, "base"] / 1024, r[x, "new"] / 1024, f[x, "base"], f[x, "new"], c[x, "base"], c[x, "new"] }' \
        "$OUTDIR/rss.csv" | sort -n
    echo
    echo "grid --timing (seconds; busy = each thread's time in the finder; tests/busy-s = a"
    echo "thread's pair tests per second of its busy time, summed over threads / threads):"
    while read -r line; do
        echo "$line" | awk '{
            sub(/^\{"/, ""); n = split($0, f, ", \""); out = "";
            for (i = 1; i <= n; i++) if (f[i] ~ /^(scene|build_dir|threads|sim_s|broad_s|walls_s|sort_s|resolve_s|motion_s|output_s|input_s|user_s|sys_s|minflt|nivcsw)"/) out = out " " f[i];
            tests = 0; if (match($0, /"pair_tests": [0-9]+/)) tests = substr($0, RSTART + 14, RLENGTH - 14) + 0;
            if (match($0, /"threads_busy_s": \[[^]]*\]/)) { b = substr($0, RSTART + 19, RLENGTH - 20); m = split(b, x, ", "); mx = 0; s = 0; for (i = 1; i <= m; i++) { s += x[i]; if (x[i] > mx) mx = x[i] } out = out sprintf(" busy_max: %.4f busy_mean: %.4f", mx, s / m); if (s > 0) out = out sprintf(" tests/busy-s/thread: %.3g", tests / s) }
            gsub(/"/, "", out); print out }'
    done <"$OUTDIR/timing.jsonl"
} | tee "$OUTDIR/table.txt"
[[ -n "${OUT:-}" ]] && echo "raw data and table in $OUTDIR" >&2
exit 0
