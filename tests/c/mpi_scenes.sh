#!/usr/bin/env bash
# mpi_scenes.sh BUILD_DIR: the MPI variant (variants/mpi.c) against seq, under Open MPI's mpirun
# and alone (a singleton: one rank, no launcher), in BUILD_DIR (build, or build/asan).
#
#   1. --describe and --help, alone and under mpirun (one line, from rank 0);
#   2. every hand scene (tests/c/scenes): alone at 1 and 2 threads, and under mpirun at 2, 3
#      and 4 ranks, in %.8f against the derivations' outputs and in --precise against seq;
#   3. random scenes (the generator's fast discs, dense and sparse, slow listed ones, touching
#      lattices, N from 0 to 34,000, perf and print) at 1-4 ranks x 1-2 threads against seq,
#      --precise, byte for byte; input on stdin, which only rank 0 reads;
#   4. bad input and bad command lines: status 2 from mpirun, nothing on stdout, one line on
#      stderr from rank 0 alone (mpirun adds its own report of a nonzero exit; `mpirun -q`
#      leaves the one line alone); --replay refused on several ranks;
#   5. --timing: one JSON line from rank 0 with every variant's fields and the ranks' own
#      (ranks, mpi_s, mpi_s_mean, mpi_bytes_step, mpi_bytes_step_mean, rss_mib_max,
#      rss_mib_sum), sane: bytes moved with 2 ranks and none alone, pair tests summed over the
#      ranks, the writers of every rank listed, the candidates grid counts;
#   6. a rank killed in the middle of a run: mpirun ends with a nonzero status and says so,
#      within a time limit (no hang);
#   7. for build/asan: LeakSanitizer on a few runs (the build turns it off by default: Open
#      MPI's own blocks; variants/mpi/mpi_ranks.c says why), with the exact unwinder and the
#      suppressions of Open MPI's libraries, so that the core's and the variant's leaks show.
#
# Where mpirun or the mpi binary is missing (no Open MPI: scripts/setup.sh --test installs it as
# root), the script says why and passes; with CI set it fails instead.
#
# Cost: each mpirun start takes 0.15-0.4 s here (Open MPI's start-up, on 2 shared cores), so
# not every scene runs at every (ranks, threads) pair. Each hand scene runs alone at 1 and 2
# threads and under mpirun at two of 2, 3 and 4 ranks (in turn from scene to scene, the
# threads alternating): they have at most 5 discs and one time slice (K = 1), which the last
# rank looks at whatever the ranks, so the ranks differ there only in how many have nothing to
# send. The random scenes whose ranks share several slices (K > 1), the ties and print mode run
# at all eight pairs; the others at (1,1) (2,2) (3,1) (4,2). The runs set OMPI_MCA_pml=ob1 and
# OMPI_MCA_btl=self,vader (shared memory), which start in half the time of the default probe
# of UCX (the --timing check runs with the defaults), and OMPI_MCA_odls_base_sigkill_timeout=0:
# mpirun otherwise waits a second before it ends the ranks of a job that exits nonzero. For
# build/asan (runs 2-5x slower) each hand scene runs once alone and once under mpirun, and the
# random scenes at (1,1) (2,2) (3,1) (4,2) and without the 34,000-disc one; part 6 is left out
# (the optimised build runs it: it checks mpirun, not the variant's memory).
set -euo pipefail
source "$(dirname "$0")/lib.sh"
SCENES=$HERE/scenes
V=mpi

skip() {
    if [ -n "${CI:-}" ]; then
        echo "FAIL: $1 (CI is set: the MPI tests must run)"
        exit 1
    fi
    echo "SKIP: $1"
    exit 0
}
BUILT=$(print_variants)
if ! [[ " $BUILT " == *" $V "* ]]; then
    skip "the Makefile builds no $V variant here (no mpicc; to run these tests: sudo apt-get install openmpi-bin libopenmpi-dev)"
fi
if ! command -v mpirun >/dev/null 2>&1; then
    skip "mpirun is missing (to run these tests: sudo apt-get install openmpi-bin libopenmpi-dev)"
fi
[ -x "$B/$V" ] || { echo "FAIL: $B/$V is missing (make all asan)"; exit 1; }
[ -x "$B/seq" ] || { echo "FAIL: $B/seq is missing"; exit 1; }

# Open MPI refuses to start as root unless told; the tests run as root in CI's container.
if [ "$(id -u)" = 0 ]; then
    export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
fi
FAST_MCA=(env OMPI_MCA_pml=ob1 OMPI_MCA_btl=self,vader OMPI_MCA_odls_base_sigkill_timeout=0)
# Waiting threads sleep: the runs oversubscribe the 2 cores (4 ranks of 2 threads).
export OMP_WAIT_POLICY=passive
ASAN=0
[[ "$B" == *asan* ]] && ASAN=1


# run OUT ERR CMD...: never fails the script; sets $rc.
run() {
    local out=$1 err=$2
    shift 2
    rc=0
    "$@" >"$out" 2>"$err" </dev/null || rc=$?
}

# mpi RANKS ARGS...: the variant under mpirun (ranks 1-4, oversubscribed), the fast transports.
mpi() {
    local ranks=$1
    shift
    "${FAST_MCA[@]}" mpirun --oversubscribe -np "$ranks" "$B/$V" "$@"
}

# A job whose ranks did not all start: Open MPI's start-up, not the variant, failed (seen once
# with 4 ranks of 2 threads on 2 busy cores). Such a run is tried once more, and says so.
START_FAILED='did not call "init" before exiting|MPI_Init_thread failed|failed to start'

# check WHAT EXPECTED CMD...: CMD's stdout is EXPECTED's bytes, status 0, stderr empty.
check() {
    local what=$1 exp=$2
    shift 2
    run "$TMP/out" "$TMP/err" "$@"
    if [ "$rc" != 0 ] && grep -Eq "$START_FAILED" "$TMP/err"; then
        echo "# $what: the ranks did not all start (status $rc); once more"
        run "$TMP/out" "$TMP/err" "$@"
    fi
    if [ "$rc" != 0 ] || [ -s "$TMP/err" ]; then
        bad "$what: status $rc, stderr: $(tr '\n' ' ' < "$TMP/err" | head -c 1500)"
    elif cmp -s "$TMP/out" "$exp"; then
        ok
    else
        bad "$what: output differs from $(basename "$exp"): $(cmp "$TMP/out" "$exp" 2>&1 | head -1)"
    fi
}


# ---------------------------------------------------------------------------------------------
part "--describe, --help"
run "$TMP/out" "$TMP/err" "$B/$V" --describe
if [ "$rc" = 0 ] && [ ! -s "$TMP/err" ] && python3 -c '
import json, sys
d = json.loads(open(sys.argv[1]).read())
sys.exit(not (d["name"] == "mpi" and d["mpi"] is True and d["exact"] is True and d["parallel"] is True))
' "$TMP/out"; then ok; else bad "$V --describe: status $rc: $(head -c 300 "$TMP/out") $(head -c 300 "$TMP/err")"; fi
cp "$TMP/out" "$TMP/describe"
if ((!ASAN)); then
    # Every other variant says "mpi": false.
    for v in $BUILT; do
        [ "$v" = "$V" ] && continue
        if "$B/$v" --describe 2>/dev/null | grep -q '"mpi":false'; then ok; else bad "$v --describe lacks \"mpi\":false"; fi
    done
fi
check "mpirun -np 3 $V --describe: rank 0's one line" "$TMP/describe" mpi 3 --describe
run "$TMP/out" "$TMP/err" mpi 2 --help
if [ "$rc" = 0 ] && [ ! -s "$TMP/err" ] && [ "$(grep -c '^usage:' "$TMP/out")" = 1 ] &&
    grep -q 'mpirun -np R' "$TMP/out"; then ok; else bad "mpirun -np 2 $V --help: status $rc, $(grep -c '^usage:' "$TMP/out") usage lines"; fi

# ---------------------------------------------------------------------------------------------
part "hand scenes"
s=0
for input in "$SCENES"/*.in; do
    name=$(basename "$input" .in)
    exp=$SCENES/$name.out
    scene_args "$input"
    # --precise reference: seq's own (the derivations' values are exact in binary but the
    # generated ones are not).
    if ! "$B/seq" --precise "${args[@]}" "$input" >"$TMP/precise.exp" 2>"$TMP/err"; then
        bad "seq --precise $name failed: $(head -c 300 "$TMP/err")"
        continue
    fi
    a=$((1 + s % 2)) b=$((2 - s % 2))
    s=$((s + 1))
    check "$V alone --threads $a $name" "$exp" "$B/$V" --threads "$a" "${args[@]}" "$input"
    if ((ASAN)); then
        ranks=$((2 + s % 3))
        check "mpirun -np $ranks $V --threads $b --precise $name" "$TMP/precise.exp" \
            mpi "$ranks" --threads "$b" --precise "${args[@]}" "$input"
        continue
    fi
    check "$V alone --threads $b --precise $name" "$TMP/precise.exp" "$B/$V" --threads "$b" --precise "${args[@]}" "$input"
    r1=$((2 + s % 3)) r2=$((2 + (s + 1) % 3))
    check "mpirun -np $r1 $V --threads $a $name" "$exp" mpi "$r1" --threads "$a" "${args[@]}" "$input"
    check "mpirun -np $r2 $V --threads $b --precise $name" "$TMP/precise.exp" mpi "$r2" --threads "$b" --precise "${args[@]}" "$input"
done

# ---------------------------------------------------------------------------------------------
part "random scenes"
# x$i.pairs: the (ranks, threads) pairs scene i runs at: all eight, or four.
ALL_PAIRS="1,1 1,2 2,1 2,2 3,1 3,2 4,1 4,2"
SOME_PAIRS="1,1 2,2 3,1 4,2"
i=0
add_gen() { # PAIRS N L r S MODE SEED
    i=$((i + 1))
    printf '%s %s %s %s\n%s\n' "$2" "$3" "$4" "$5" "$6" >"$TMP/x$i.in"
    echo "--seed $7" >"$TMP/x$i.args"
    echo "$1" >"$TMP/x$i.pairs"
}
add_slow() { # PAIRS, then slow_scene's arguments (mode perf)
    i=$((i + 1))
    slow_scene "$2" "$3" "$4" "$5" perf "$6" "$7" "${8:-1}" >"$TMP/x$i.in"
    echo "--seed $6" >"$TMP/x$i.args"
    echo "$1" >"$TMP/x$i.pairs"
}
add_gen "$SOME_PAIRS" 0 10 1 3 perf 1           # no disc
add_gen "$SOME_PAIRS" 1 10 1 3 perf 2           # one disc
add_gen "$SOME_PAIRS" 2 4 1 5 print 3           # two discs in a tiny box, print mode
add_gen "$ALL_PAIRS" 3000 300 0.1 2 perf 4      # fast, small r: K = 4 slices a step
add_gen "$ALL_PAIRS" 20000 2000 0.25 1 perf 5   # fast, 20,000 discs, K = 4
add_gen "$SOME_PAIRS" 2000 100 0.5 1 perf 6     # very dense: most discs overlap
add_gen "$SOME_PAIRS" 300 10000 2 2 perf 7      # sparse: crosses the box in a step
add_gen "$ALL_PAIRS" 400 100 1 3 print 8        # dense fast, print mode
add_slow "$SOME_PAIRS" 1000 150 1 2 41 0.2      # slow, dense: one slice, the last rank's
add_slow "$SOME_PAIRS" 300 400 1 2 43 1         # slow, sparse
add_slow "$SOME_PAIRS" 500 100 1 2 45 0.25 2    # half listed slow, half generated fast
i=$((i + 1))
lattice_scene 15 2 3 perf 48 >"$TMP/x$i.in" # 225 touching discs: exact ties
: >"$TMP/x$i.args"
echo "$ALL_PAIRS" >"$TMP/x$i.pairs"
if ((!ASAN)); then
    # Above 32,768 discs a team cuts each slice into bands (grid_run_team) in every rank.
    add_gen "1,1 2,2 3,2" 34000 3000 0.25 1 perf 9
fi
for k in $(seq 1 "$i"); do
    read -r -a args <"$TMP/x$k.args" || args=()
    read -r -a pairs <"$TMP/x$k.pairs"
    ((ASAN)) && read -r -a pairs <<<"$SOME_PAIRS"
    if ! "$B/seq" --precise "${args[@]}" "$TMP/x$k.in" >"$TMP/ref" 2>"$TMP/err"; then
        bad "seq x$k: $(head -c 300 "$TMP/err")"
        continue
    fi
    for pair in "${pairs[@]}"; do
        ranks=${pair%,*} threads=${pair#*,}
        if [ "$ranks" = 1 ] && [ "$threads" = 1 ]; then
            # One rank as a singleton, no mpirun.
            check "$V alone x$k ($(head -n 1 "$TMP/x$k.in"))" "$TMP/ref" \
                "$B/$V" --threads 1 --precise "${args[@]}" "$TMP/x$k.in"
        else
            check "mpirun -np $ranks $V --threads $threads x$k ($(head -n 1 "$TMP/x$k.in"))" "$TMP/ref" \
                mpi "$ranks" --threads "$threads" --precise "${args[@]}" "$TMP/x$k.in"
        fi
    done
done
# The input on stdin, which mpirun gives rank 0 only.
"$B/seq" --seed 4 "$TMP/x4.in" >"$TMP/x4.ref"
rc=0
"${FAST_MCA[@]}" mpirun --oversubscribe -np 3 "$B/$V" --threads 1 --seed 4 - <"$TMP/x4.in" >"$TMP/out" 2>"$TMP/err" || rc=$?
if [ "$rc" = 0 ] && [ ! -s "$TMP/err" ] && cmp -s "$TMP/out" "$TMP/x4.ref"; then ok; else bad "mpirun -np 3 $V - (stdin): status $rc, $(head -c 300 "$TMP/err")"; fi

# ---------------------------------------------------------------------------------------------
part "bad input"
# expect_error WHAT WANT CMD...: status 2, no stdout, exactly one line of stderr that starts
# "mpi: WANT", none other from the variant (mpirun's own report of the exit, without -q, is
# lines of dashes and prose that name no variant: they are left out of the count).
expect_error() {
    local what=$1 want=$2
    shift 2
    run "$TMP/out" "$TMP/err" "$@"
    local ours all
    ours=$(grep -c "^$V: " "$TMP/err" || true)
    all=$(wc -l <"$TMP/err")
    if [ "$rc" = 2 ] && [ ! -s "$TMP/out" ] && [ "$ours" = 1 ] && head -n 1 "$TMP/err" | grep -q "^$V: $want"; then
        ok
    else
        bad "$what: expected status 2, no stdout, one line '$V: $want...'; got status $rc," \
            "$(wc -c <"$TMP/out") bytes of stdout, $ours of our lines ($all in all): $(head -c 300 "$TMP/err")"
    fi
    # With mpirun -q, or alone, that line is all of stderr.
    if [[ "$*" != *mpirun* ]] || [[ "$*" == *" -q "* ]]; then
        [ "$all" = 1 ] && ok || bad "$what: $all lines of stderr, expected 1: $(head -c 300 "$TMP/err")"
    fi
}
printf '2 100 1 1\nperf\n0 nan 10 1 1\n' >"$TMP/bad1.in"
printf '2 100 1 1\nfast\n' >"$TMP/bad2.in"
printf '3 100 1 1\nperf\n0 10 10 1 1\n0 20 20 1 1\n' >"$TMP/bad3.in"
expect_error "alone, x NaN" "input: line 3: " "$B/$V" "$TMP/bad1.in"
expect_error "mpirun -q -np 2, x NaN" "input: line 3: " "${FAST_MCA[@]}" mpirun -q -np 2 "$B/$V" "$TMP/bad1.in"
expect_error "mpirun -np 3, bad mode" "input: line 2: " "${FAST_MCA[@]}" mpirun --oversubscribe -np 3 "$B/$V" "$TMP/bad2.in"
if ((!ASAN)); then
    expect_error "mpirun -q -np 4, duplicate index" "input: line 4: " "${FAST_MCA[@]}" mpirun -q --oversubscribe -np 4 "$B/$V" --threads 2 "$TMP/bad3.in"
    printf '2000000000 100 1 1\nperf\n' >"$TMP/bad4.in"
    expect_error "mpirun -q -np 2, N refused up front" "input: line 1: " "${FAST_MCA[@]}" mpirun -q -np 2 "$B/$V" "$TMP/bad4.in"
fi
expect_error "mpirun -q -np 2, unknown option" "usage: " "${FAST_MCA[@]}" mpirun -q -np 2 "$B/$V" --bogus
expect_error "mpirun -q -np 3, --threads 0" "usage: " "${FAST_MCA[@]}" mpirun -q --oversubscribe -np 3 "$B/$V" --threads 0
expect_error "alone, --threads abc" "usage: " "$B/$V" --threads abc
expect_error "mpirun -q -np 2, missing input" "cannot read " "${FAST_MCA[@]}" mpirun -q -np 2 "$B/$V" "$TMP/no-such-file.in"
expect_error "mpirun -q -np 2, --replay" "usage: --replay runs as one process" "${FAST_MCA[@]}" mpirun -q -np 2 "$B/$V" --replay "$TMP/bad1.in"
# Alone, --replay works as every exact variant's (replay_scenes.sh checks its states).
printf '2 100 1\n0 0 10 10 5 0\n0 1 20 10 -5 0\n' >"$TMP/replay.in"
"$B/seq" --replay "$TMP/replay.in" >"$TMP/replay.exp"
check "$V --replay alone" "$TMP/replay.exp" "$B/$V" --replay "$TMP/replay.in"

# ---------------------------------------------------------------------------------------------
part "--timing"
# check_timing WHAT RANKS THREADS: the last run's stderr is one JSON line with every variant's
# fields and the ranks' own, sane.
check_timing() {
    local what=$1 ranks=$2 threads=$3 problems
    if [ "$rc" != 0 ] || [ "$(wc -l <"$TMP/err")" != 1 ]; then
        bad "$what: status $rc, $(wc -l <"$TMP/err") lines of stderr: $(head -c 400 "$TMP/err")"
        return
    fi
    problems=$(python3 -c '
import json, sys
t = json.loads(open(sys.argv[1]).read())
ranks, threads, candidates = int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
p = []
for k in ("variant", "threads", "n", "steps", "input_s", "sim_s", "broad_s", "walls_s", "sort_s",
          "resolve_s", "motion_s", "output_s", "pair_tests", "candidates", "pair_collisions",
          "wall_collisions", "threads_busy_s", "threads_pairs", "threads_chunks", "ranks", "mpi_s",
          "mpi_s_mean", "mpi_bytes_step", "mpi_bytes_step_mean", "rss_mib_max", "rss_mib_sum"):
    if k not in t:
        p.append("no key " + k)
if not p:
    if t["variant"] != "mpi" or t["ranks"] != ranks or t["threads"] != threads:
        p.append("variant, ranks or threads")
    if not 0 <= t["mpi_s_mean"] <= t["mpi_s"] + 1e-6 or t["mpi_s"] > t["sim_s"] + t["input_s"] + t["output_s"] + 5:
        p.append("mpi_s")
    moved = t["mpi_bytes_step"] > 0 and t["mpi_bytes_step_mean"] > 0
    if moved != (ranks > 1) or t["mpi_bytes_step_mean"] > t["mpi_bytes_step"]:
        p.append("mpi_bytes_step (bytes move between ranks, and only then)")
    if not 0 < t["rss_mib_max"] <= t["rss_mib_sum"] <= ranks * t["rss_mib_max"] + 0.1:
        p.append("rss_mib")
    if not all(len(t[k]) == ranks * threads for k in ("threads_busy_s", "threads_pairs", "threads_chunks")):
        p.append("the writers of every rank listed")
    elif sum(t["threads_pairs"]) != t["pair_tests"] or t["pair_tests"] <= 0:
        p.append("pair_tests is not the sum over the ranks writers")
    if t["candidates"] != candidates:
        p.append("candidates %d, grid counts %d" % (t["candidates"], candidates))
print("; ".join(p))
' "$TMP/err" "$ranks" "$threads" "$GRID_CANDIDATES")
    if [ -z "$problems" ]; then ok; else bad "$what: $problems: $(head -c 600 "$TMP/err")"; fi
}
printf '3000 300 0.1 3\nperf\n' >"$TMP/timing.in"
"$B/grid" --threads 2 --timing "$TMP/timing.in" >"$TMP/timing.ref" 2>"$TMP/err"
GRID_CANDIDATES=$(json_field candidates "$TMP/err")
run "$TMP/out" "$TMP/err" "$B/$V" --threads 2 --timing "$TMP/timing.in"
check_timing "$V --timing alone" 1 2
cmp -s "$TMP/out" "$TMP/timing.ref" && ok || bad "$V --timing alone: output differs from grid's"
# With Open MPI's default transports (no FAST_MCA).
run "$TMP/out" "$TMP/err" mpirun --oversubscribe -np 2 "$B/$V" --threads 1 --timing "$TMP/timing.in"
check_timing "mpirun -np 2 $V --timing (default transports)" 2 1
cmp -s "$TMP/out" "$TMP/timing.ref" && ok || bad "mpirun -np 2 $V --timing: output differs from grid's"
run "$TMP/out" "$TMP/err" mpi 3 --threads 2 --timing "$TMP/timing.in"
check_timing "mpirun -np 3 $V --threads 2 --timing" 3 2

# ---------------------------------------------------------------------------------------------
if ((!ASAN)); then
    part "a rank killed"
    # A run of seconds; once both ranks are up, rank processes are mpirun's children: one is
    # killed, and mpirun must end with a nonzero status and a message within 60 s.
    printf '200000 40000 1 1000\nperf\n' >"$TMP/long.in"
    "${FAST_MCA[@]}" mpirun -np 2 "$B/$V" --threads 1 "$TMP/long.in" >"$TMP/out" 2>"$TMP/err" &
    launcher=$!
    ranks=()
    for _ in $(seq 100); do
        mapfile -t ranks < <(pgrep -P "$launcher" -f "$V" || true)
        [ "${#ranks[@]}" -ge 2 ] && break
        sleep 0.1
    done
    if [ "${#ranks[@]}" -lt 2 ]; then
        bad "a rank killed: the ranks did not start (children of mpirun: ${ranks[*]:-none})"
        kill "$launcher" 2>/dev/null || true
    else
        sleep 0.5
        kill -9 "${ranks[1]}"
        for _ in $(seq 600); do
            kill -0 "$launcher" 2>/dev/null || break
            sleep 0.1
        done
        if kill -0 "$launcher" 2>/dev/null; then
            bad "a rank killed: mpirun still runs 60 s later (a hang)"
            kill -9 "$launcher" "${ranks[0]}" 2>/dev/null || true
        else
            rc=0
            wait "$launcher" || rc=$?
            if [ "$rc" != 0 ] && [ -s "$TMP/err" ]; then ok; else bad "a rank killed: mpirun's status $rc, stderr: $(head -c 300 "$TMP/err")"; fi
        fi
    fi
fi

# ---------------------------------------------------------------------------------------------
if ((ASAN)); then
    part "leaks"
    # LeakSanitizer on, the exact unwinder (a start takes about a second), Open MPI's libraries
    # suppressed (the binary's list): alone, under mpirun (-x passes ASAN_OPTIONS to the
    # ranks), and on an input error.
    LEAKS=detect_leaks=1:fast_unwind_on_malloc=0:print_suppressions=0
    check "$V alone, leak check" "$TMP/timing.ref" env ASAN_OPTIONS=$LEAKS "$B/$V" --threads 2 "$TMP/timing.in"
    check "mpirun -np 2 $V, leak check" "$TMP/timing.ref" env ASAN_OPTIONS=$LEAKS "${FAST_MCA[@]}" \
        mpirun -np 2 -x ASAN_OPTIONS "$B/$V" --threads 2 "$TMP/timing.in"
    expect_error "mpirun -q -np 2, x NaN, leak check" "input: line 3: " env ASAN_OPTIONS=$LEAKS \
        "${FAST_MCA[@]}" mpirun -q -np 2 -x ASAN_OPTIONS "$B/$V" "$TMP/bad1.in"
fi
part

finish
