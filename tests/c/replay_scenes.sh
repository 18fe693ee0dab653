#!/usr/bin/env bash
# replay_scenes.sh BUILD_DIR: `--replay` (variants/core/sim_replay.c) of the binaries in
# BUILD_DIR (build, or build/asan).
#
#   1. replaying seq's own --precise states gives seq's next states byte for byte (%.17g is
#      exact in double), for every exact variant at 1 and 2 threads, one process for all
#      steps, the states given in reverse order too;
#   2. the events it names: a head-on pair, a wall, free motion, on a hand-computed scene;
#   3. the print flag prints only the flagged particles; the binary form (in and out) gives
#      what the text form gives;
#   4. every class of bad replay input: status 2, one line on stderr, nothing on stdout.
#
# Exits non-zero on any failure; the last line is "N passed, M failed".
set -euo pipefail
source "$(dirname "$0")/lib.sh"

# The exact variants, from their own --describe lines.
ALL=$(print_variants)
EXACT=()
for v in $ALL; do
    if "$B/$v" --describe </dev/null | grep -q '"exact": *true'; then EXACT+=("$v"); fi
done
[ "${#EXACT[@]}" -gt 1 ] && ok || bad "no exact variants found in $B"

# 1. Replay of seq's trajectory: a dense scene (many collisions a step) of the generator's.
n=300 L=400 steps=6
if [ "$B" != build ]; then n=120 L=250; fi
printf '%s %s 1 %s\nprint\n' "$n" "$L" "$steps" >"$TMP/scene.in"
"$B/seq" --precise --seed 5 "$TMP/scene.in" >"$TMP/seq.out"
# States 0..steps-1 as replay input, and what must come out: states 1..steps with no counts.
{ echo "$n $L 1"; awk 'NF == 6' "$TMP/seq.out"; } >"$TMP/states"
awk -v s="$steps" 'NF == 6 && $1 > 0 { print } NF == 8 && $1 == s { print $1, $2, $3, $4, $5, $6 }' \
    "$TMP/seq.out" >"$TMP/want"
{ echo "$n $L 1"; awk 'NF == 6' "$TMP/seq.out" | sort -s -k1,1nr; } >"$TMP/reversed"
for v in "${EXACT[@]}"; do
    for t in 1 2; do
        "$B/$v" --replay --threads "$t" "$TMP/states" | cut -d' ' -f1-6 >"$TMP/got"
        if cmp -s "$TMP/got" "$TMP/want"; then ok; else
            bad "$v --replay --threads $t: successors differ from seq's next states"
            diff "$TMP/want" "$TMP/got" | head -n 4 | sed 's/^/    /' || true
        fi
    done
done
"$B/seq" --replay "$TMP/reversed" | cut -d' ' -f1-6 | sort -s -k1,1n >"$TMP/got"
if cmp -s "$TMP/got" "$TMP/want"; then ok; else bad "seq --replay of states in reverse order"; fi

# 2. Events: 0 and 1 meet head-on at t = 0.8; 2 hits y = L - r at t = 1/6; 3 moves freely.
printf '4 100 1\n0 0 10 10 5 0\n0 1 20 10 -5 0\n0 2 50 98.5 0 3\n0 3 50 50 1 1\n' >"$TMP/events"
"$B/seq" --replay "$TMP/events" >"$TMP/got"
printf '%s\n' "1 0 13 10 -5 0 pair 1 0.80000000000000004" "1 1 17 10 5 0 pair 0 0.80000000000000004" \
    "1 2 50 96.5 0 -3 wall -1 0.16666666666666666" "1 3 51 51 1 1 free -1 0" >"$TMP/want"
if cmp -s "$TMP/got" "$TMP/want"; then ok; else
    bad "seq --replay events:"
    diff "$TMP/want" "$TMP/got" | sed 's/^/    /' || true
fi

# 3. The print flag.
printf '4 100 1\n0 0 10 10 5 0 0\n0 1 20 10 -5 0 1\n0 2 50 98.5 0 3 0\n0 3 50 50 1 1\n' >"$TMP/flags"
if [ "$("$B/seq" --replay "$TMP/flags" | cut -d' ' -f2 | tr '\n' ' ')" = "1 3 " ]; then ok; else
    bad "seq --replay with print flags printed other particles"
fi

# 3b. The binary form gives what the text form gives (a copy of the states with flags).
python3 - "$TMP/states" "$TMP/states.bin" <<'PY'
import struct, sys
lines = open(sys.argv[1]).read().split("\n")
n, L, r = lines[0].split()
out = [b"CBREPLAY", struct.pack("=qdd", int(n), float(L), float(r))]
rows = [line.split() for line in lines[1:] if line.strip()]
for k in range(0, len(rows), int(n)):
    state = rows[k:k + int(n)]
    out.append(struct.pack("=q", int(state[0][0])))
    out += [struct.pack("=dddd", *map(float, row[2:6])) for row in state]
    out.append(bytes(i % 2 for i in range(int(n))))
open(sys.argv[2], "wb").write(b"".join(out))
PY
"$B/seq" --replay "$TMP/states" | awk '$2 % 2 == 1' >"$TMP/want"
# Its successors are binary records (sim_replay.c), written out here as the text form's lines.
"$B/seq" --replay "$TMP/states.bin" | python3 -c '
import struct, sys
data, size = sys.stdin.buffer.read(), struct.calcsize("=qidddddiB")
for at in range(0, len(data), size):
    k, i, x, y, vx, vy, t, j, e = struct.unpack_from("=qidddddiB", data, at)
    reals = " ".join("%.17g" % v for v in (x, y, vx, vy))
    print(k, i, reals, ("free", "pair", "wall")[e], j, "%.17g" % t)
' >"$TMP/got"
if cmp -s "$TMP/got" "$TMP/want"; then ok; else bad "seq --replay of the binary form differs from the text form"; fi
head -c 100 "$TMP/states.bin" >"$TMP/short.bin"
rc=0
"$B/seq" --replay "$TMP/short.bin" >"$TMP/out" 2>"$TMP/err" || rc=$?
if [ "$rc" = 2 ] && [ ! -s "$TMP/out" ] && [ "$(wc -l <"$TMP/err")" = 1 ] &&
    grep -q '^seq: replay: binary state 1 is cut short' "$TMP/err"; then ok; else
    bad "a cut-short binary state: status $rc, stderr $(head -c 200 "$TMP/err")"
fi

# 4. Bad input.
bad_input() {  # WHAT TEXT
    local rc=0
    printf '%b' "$2" | "$B/seq" --replay >"$TMP/out" 2>"$TMP/err" || rc=$?
    if [ "$rc" = 2 ] && [ ! -s "$TMP/out" ] && [ "$(wc -l <"$TMP/err")" = 1 ] &&
        grep -q '^seq: replay: line [0-9]*: ' "$TMP/err"; then ok; else
        bad "$1: status $rc, stdout $(head -c 100 "$TMP/out"), stderr $(head -c 200 "$TMP/err")"
    fi
}
bad_input "empty input" ''
bad_input "scene line with S" '2 100 1 5\n'
bad_input "r too large" '2 100 60\n'
bad_input "negative N" '-1 100 1\n'
bad_input "particle out of order" '2 100 1\n0 1 5 5 1 1\n0 0 5 5 1 1\n'
bad_input "state cut short" '2 100 1\n0 0 5 5 1 1\n'
bad_input "label changes within a state" '2 100 1\n0 0 5 5 1 1\n1 1 7 7 1 1\n'
bad_input "NaN velocity" '1 100 1\n0 0 5 5 nan 1\n'
bad_input "infinite position" '1 100 1\n0 0 inf 5 1 1\n'
bad_input "garbage token" '1 100 1\n0 0 5 5 1 x\n'
bad_input "too many fields" '1 100 1\n0 0 5 5 1 1 1 1\n'
bad_input "bad print flag" '1 100 1\n0 0 5 5 1 1 2\n'
bad_input "negative step" '1 100 1\n-1 0 5 5 1 1\n'
# Any finite real prints in full (up to 309 integer digits) and reads back; longer is refused.
bad_input "huge token" "1 100 1\n0 0 5 5 1 $(printf '1%.0s' $(seq 400))\n"

finish
