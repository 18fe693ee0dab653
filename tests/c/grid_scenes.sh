#!/usr/bin/env bash
# grid_scenes.sh BUILD_DIR: scene tests of the grid and relative variants against seq.
#
#   tests/c/grid_scenes.sh build          # the optimised build
#   tests/c/grid_scenes.sh build/asan     # ASan+UBSan build (scenes scaled down: ~5x slower)
#   tests/c/grid_scenes.sh gen KIND ARGS  # print one generated input file (see gen_scene)
#
# grid must be byte-identical (--precise, cmp) to seq on every scene and for 1-4 and 8 threads:
# random scenes from the binaries' own generator (fast: speeds L/8r..L/4) and listed scenes
# from gen_scene (slow, dense with overlaps, huge sparse L, mixed and outlier speeds, contacts
# placed exactly on grid slice and cell boundaries), and hand-computed scenes.
#
# relative must equal seq byte for byte on the hand-computed scenes (head-on, touching at start,
# overlap at start, contact at t = 1, tangent graze, tangent miss, corner hit, Newton's cradle,
# 4-body tie, ...) and on the lattice, whose contact times are all exact in binary. On the other
# scenes it is run for one step and must stay within REL_TOL = 1e-9 of L in every position and
# velocity, with the same pcoll/wcoll everywhere. Why one step and 1e-9: relative's contact
# times differ from seq's by rounding (~1e-16 relative), which moves a colliding particle by a
# few ulps of its coordinates: measured, the largest one-step deviation over these scenes is
# ~3e-12 L (a 1e6-times-faster outlier), most are ~1e-14 L or below. Over more steps every
# collision multiplies a deviation by about (free path / r), hundreds in the report's scenes, so
# after a few steps the same rounding reaches 1e-6 L and beyond (measured: 1.7e-6 L after 4 steps
# of report_like) without any disagreement in the test itself; one step keeps chaos out. 1e-9
# leaves ~300x headroom and still catches any real disagreement: a different accept/reject
# decision moves a particle by ~r (>= 1e-7 L here) and changes pcoll/wcoll.
#
# Exits non-zero on any failure; the last line is "N passed, M failed".
set -euo pipefail

# Deterministic scene generator (python3). Kinds:
#   slow N L R S SEED [VMIN VMAX]   every particle listed, x, y uniform in [r, L-r], speed uniform
#                                   in [VMIN, VMAX] (default 0.5 1.5), direction uniform
#   mixed N L R S SEED              speeds log-uniform over 1e-3 .. L: many "wide" particles
#   outliers N L R S SEED [EVERY]   speeds ~1, and every EVERY-th (default 50th) particle 1e3..1e6
#                                   times faster
#   lattice N L R S                 a square lattice (spacing 4r) moving on the axes at 2r per
#                                   step: many head-on contacts at exactly the same time
#   edges                           pairs whose contact times are 1/4, 1/2, 3/4, 1 and whose
#                                   boxes / contact points sit on grid cell edges (the grid's
#                                   plan for this scene, K = 4, replayed in double)
gen_scene() {
    python3 - "$@" <<'PY'
import math, random, sys

def out(n, L, r, S, parts, mode="perf"):
    print(f"{n} {L!r} {r!r} {S}")
    print(mode)
    for i, (x, y, vx, vy) in enumerate(parts):
        print(f"{i} {x!r} {y!r} {vx!r} {vy!r}")

kind, args = sys.argv[1], sys.argv[2:]
if kind in ("slow", "mixed", "outliers"):
    n, L, r, S, seed = int(args[0]), float(args[1]), float(args[2]), int(args[3]), int(args[4])
    vmin, vmax = (float(args[5]), float(args[6])) if len(args) > 6 else (0.5, 1.5)
    every = int(args[5]) if kind == "outliers" and len(args) > 5 else 50
    rng = random.Random(seed)
    parts = []
    for i in range(n):
        x, y = rng.uniform(r, L - r), rng.uniform(r, L - r)
        if kind == "slow":
            sp = rng.uniform(vmin, vmax)
        elif kind == "mixed":
            sp = math.exp(rng.uniform(math.log(1e-3), math.log(L)))
        else:
            sp = rng.uniform(0.5, 1.5) * (10 ** rng.uniform(3, 6) if i % every == 0 else 1)
        a = rng.uniform(0, 2 * math.pi)
        parts.append((x, y, sp * math.cos(a), sp * math.sin(a)))
    out(n, L, r, S, parts)
elif kind == "lattice":
    n, L, r, S = int(args[0]), float(args[1]), float(args[2]), int(args[3])
    side = int(math.isqrt(n))
    parts = []
    for i in range(n):
        gx, gy = i % side, i // side
        v = 2 * r if (gx + gy) % 2 == 0 else -2 * r
        parts.append((r + 4 * r * gx + 2 * r, r + 4 * r * gy + 2 * r,
                      v if gy % 2 == 0 else 0.0, 0.0 if gy % 2 == 0 else v))
    out(n, L, r, S, parts, "print")
elif kind == "edges":
    # Background: particles moving on the axes at exactly V, so that v_ref = V; with N = 1600,
    # L = 1000: K = round(0.15 * V * sqrt(N) / L) = 4 (grid_plan.c: GRID_K_FACTOR; at 1,
    # 2 and 4 threads) and slices end at 1/4, 1/2, 3/4, 1.
    L, r, V, n = 1000.0, 1.0, 640.0, 1600
    rng = random.Random(7)
    eps = 2.0 ** -52
    delta = 4 * math.sqrt(eps) * (L + 2 * V + 4 * r)
    rpad = r + delta
    K = 4
    h = V / K + 2 * rpad
    parts = [(r, r, V, 0.0)]  # minx = miny = r exactly
    x0 = r - V - rpad         # the grid's origin on both axes
    edge = lambda k: x0 + k * h
    # Pairs meeting head-on along x at time t, the contact point on a cell edge; and pairs one
    # of whose slice boxes starts exactly on a cell edge.
    for t in (0.25, 0.5, 0.75, 1.0):
        for k in range(3, 12):
            cxp = edge(k)                 # contact point
            y = r + 6 * r + 37 * r * k + 200 * r * t
            if y > L - 2 * r:
                continue
            u = 2.0 + k / 4               # speed of each
            parts.append((cxp - r - u * t, y, u, 0.0))
            parts.append((cxp + r + u * t, y, -u, 0.0))
            # box of slice s starts on edge(k): x + t_s*vx - rpad == edge(k)
            s = int(t * K) % K
            ts = s / K
            xb = edge(k) + rpad - ts * 3.0
            parts.append((xb, y + 3 * r, 3.0, 0.0))
            parts.append((xb + 2 * r + 3.0 * 2 * t, y + 3 * r, -3.0, 0.0))
    parts = [(min(max(x, r), L - r), min(max(y, r), L - r), vx, vy) for x, y, vx, vy in parts]
    while len(parts) < n:
        x, y = rng.uniform(r, L - r), rng.uniform(r, L - r)
        d = rng.randrange(4)
        parts.append((x, y, (V, -V, 0.0, 0.0)[d], (0.0, 0.0, V, -V)[d]))
    out(n, L, r, 3, parts)
else:
    sys.exit(f"unknown scene kind {kind}")
PY
}

if [[ "${1:-}" == gen ]]; then
    shift
    gen_scene "$@"
    exit 0
fi

BUILD=${1:?usage: grid_scenes.sh BUILD_DIR}
for v in seq grid relative; do
    [[ -x "$BUILD/$v" ]] || { echo "missing $BUILD/$v (make all / make asan)"; exit 2; }
done
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
# ASan builds run ~5x slower: scale the scenes down.
SMALL=0
[[ "$BUILD" == *asan* ]] && SMALL=1
REL_TOL=${REL_TOL:-1e-9}
pass=0
fail=0

ok() { pass=$((pass + 1)); }
bad() { fail=$((fail + 1)); echo "FAIL: $*"; }

# max |dx|, |dv| over L between two --precise outputs, and the count of differing pcoll/wcoll
# (last two fields of the final block): prints "dx dv counts"; fails if the lines do not match.
deviation() {
    python3 - "$1" "$2" "$3" <<'PY'
import sys
a = open(sys.argv[1]).read().split("\n")
b = open(sys.argv[2]).read().split("\n")
L = float(sys.argv[3])
if len(a) != len(b):
    print("inf inf inf"); sys.exit(0)
dx = dv = 0.0
cnt = 0
for la, lb in zip(a, b):
    fa, fb = la.split(), lb.split()
    if len(fa) != len(fb) or fa[:2] != fb[:2]:
        print("inf inf inf"); sys.exit(0)
    if len(fa) < 6:
        continue
    dx = max(dx, abs(float(fa[2]) - float(fb[2])), abs(float(fa[3]) - float(fb[3])))
    dv = max(dv, abs(float(fa[4]) - float(fb[4])), abs(float(fa[5]) - float(fb[5])))
    if len(fa) == 8 and fa[6:] != fb[6:]:
        cnt += 1
print(f"{dx / L:.3g} {dv / L:.3g} {cnt}")
PY
}

# scene NAME FILE L SEED REL: seq reference; grid at 1-4 and 8 threads must match it byte for byte;
# REL = exact: relative must too; REL = tol: within REL_TOL; REL = none: not compared.
scene() {
    local name=$1 file=$2 L=$3 seed=$4 rel=$5
    "$BUILD/seq" --precise --seed "$seed" "$file" >"$TMP/seq.out"
    for t in 1 2 3 4 8; do
        if "$BUILD/grid" --precise --seed "$seed" --threads "$t" "$file" >"$TMP/grid.out" &&
            cmp -s "$TMP/seq.out" "$TMP/grid.out"; then
            ok
        else
            bad "$name: grid --threads $t differs from seq"
        fi
    done
    [[ "$rel" == none ]] && return 0
    if [[ "$rel" == exact ]]; then
        "$BUILD/relative" --precise --seed "$seed" --threads 2 "$file" >"$TMP/rel.out"
        if cmp -s "$TMP/seq.out" "$TMP/rel.out"; then
            ok
        else
            bad "$name: relative differs from seq"
        fi
    else
        # One step: rounding differences, not yet amplified by later collisions.
        awk 'NR == 1 { $4 = 1 } { print }' "$file" >"$TMP/one.in"
        "$BUILD/seq" --precise --seed "$seed" "$TMP/one.in" >"$TMP/seq1.out"
        "$BUILD/relative" --precise --seed "$seed" --threads 2 "$TMP/one.in" >"$TMP/rel.out"
        local dev ddx ddv dcnt
        dev=$(deviation "$TMP/seq1.out" "$TMP/rel.out" "$L")
        read -r ddx ddv dcnt <<<"$dev"
        echo "  relative vs seq, one step of $name: max |dx|/L=$ddx |dv|/L=$ddv," \
            "$dcnt differing pcoll/wcoll"
        if awk -v x="$ddx" -v v="$ddv" -v c="$dcnt" -v tol="$REL_TOL" \
            'BEGIN { exit !(x != "inf" && x + 0 <= tol + 0 && v + 0 <= tol + 0 && c == 0) }'; then
            ok
        else
            bad "$name: relative vs seq: max |dx|/L=$ddx |dv|/L=$ddv, $dcnt differing pcoll/wcoll"
        fi
    fi
}

# The large-N path under ASan, where seq is too slow for a reference: grid against itself at
# 1, 2 and 4 threads (the optimised build compares the same scene with seq).
grid_only_scene() {
    local name=$1
    shift
    gen_scene "$@" >"$TMP/$name.in"
    "$BUILD/grid" --precise --threads 1 "$TMP/$name.in" >"$TMP/g1.out"
    for t in 2 4; do
        if "$BUILD/grid" --precise --threads "$t" "$TMP/$name.in" >"$TMP/grid.out" &&
            cmp -s "$TMP/g1.out" "$TMP/grid.out"; then
            ok
        else
            bad "$name: grid --threads $t differs from --threads 1"
        fi
    done
}

# Generated by the binaries (SPEC §4): "N L r S" (perf mode) and a seed.
random_scene() {
    local name=$1 n=$2 L=$3 r=$4 s=$5 seed=$6 rel=${7:-tol}
    printf '%s %s %s %s\nperf\n' "$n" "$L" "$r" "$s" >"$TMP/$name.in"
    scene "$name" "$TMP/$name.in" "$L" "$seed" "$rel"
}

listed_scene() {
    local name=$1 L=$2 rel=$3
    shift 3
    gen_scene "$@" >"$TMP/$name.in"
    scene "$name" "$TMP/$name.in" "$L" 1 "$rel"
}

# A hand-made input, from stdin.
hand_scene() {
    local name=$1 L=$2
    cat >"$TMP/$name.in"
    scene "$name" "$TMP/$name.in" "$L" 1 exact
}

# ---- hand-computed scenes (r = 1 unless said; every contact time is exact in binary) ----
hand_scene head_on 20 <<'EOF'
2 20 1 2
print
0 8 10 2 0
1 12 10 -2 0
EOF
hand_scene touching_at_start 20 <<'EOF'
2 20 1 2
print
0 9 10 1 0
1 11 10 -1 0
EOF
hand_scene touching_at_start_oblique 40 <<'EOF'
2 40 2.5 2
print
0 10 10 1 1
1 13 14 -1 -1
EOF
hand_scene overlap_at_start 20 <<'EOF'
2 20 1 3
print
0 9.5 10 1 0
1 10.5 10 -1 0
EOF
hand_scene contact_at_t1 20 <<'EOF'
2 20 1 2
print
0 8 10 1 0
1 12 10 -1 0
EOF
hand_scene contact_at_quarter 20 <<'EOF'
2 20 1 2
print
0 7.5 10 2 0
1 10.5 10 -2 0
EOF
hand_scene tangent_graze 20 <<'EOF'
2 20 1 2
print
0 7 10 4 0
1 10 12 0 0
EOF
hand_scene tangent_miss 20 <<'EOF'
2 20 1 2
print
0 7 10 4 0
1 10 12.000000001 0 0
EOF
hand_scene corner_hit 20 <<'EOF'
1 20 1 3
print
0 1.5 1.5 -1 -1
EOF
hand_scene corner_pair_and_wall 20 <<'EOF'
2 20 1 3
print
0 2 2 -1 -1
1 5 2 -2 0
EOF
hand_scene newtons_cradle 30 <<'EOF'
5 30 1 6
print
0 3 10 2 0
1 6 10 0 0
2 8 10 0 0
3 10 10 0 0
4 12 10 0 0
EOF
hand_scene four_body_tie 20 <<'EOF'
4 20 1 3
print
0 10 6 0 4
1 10 14 0 -4
2 6 10 4 0
3 14 10 -4 0
EOF
hand_scene wall_and_pair_same_time 20 <<'EOF'
3 20 1 2
print
0 2 10 -1 0
1 4 10 -1 0
2 10 10 0 0
EOF
hand_scene at_rest 20 <<'EOF'
3 20 1 2
print
0 5 5 0 0
1 7 5 0 0
2 19 19 0 0
EOF

hand_scene absurd_speeds 10 <<'EOF'
3 10 1 2
perf
0 5 5 1e300 0
1 7 5 -1e300 0
2 2 2 1.7e308 1e308
EOF

# ---- listed scenes ----
listed_scene lattice 200 exact lattice 100 200 1 4
listed_scene edges 1000 tol edges
if ((SMALL)); then
    listed_scene slow_dense 60 tol slow 400 60 1 5 11
    listed_scene slow_huge_L 1e7 tol slow 300 1e7 1 5 12
    listed_scene slow_overlapping 20 tol slow 150 20 1 5 13
    listed_scene mixed_speeds 200 tol mixed 300 200 1 3 14
    listed_scene outliers 300 tol outliers 300 300 1 3 15
    grid_only_scene fast_blocks slow 34000 2400 1 1 16 350 700
    grid_only_scene outliers_blocks outliers 33000 3000 1 1 17 100
else
    listed_scene slow_dense 150 tol slow 3000 150 1 8 11
    listed_scene slow_huge_L 1e7 tol slow 3000 1e7 1 5 12
    listed_scene slow_overlapping 40 tol slow 600 40 1 8 13
    listed_scene mixed_speeds 500 tol mixed 2000 500 1 4 14
    listed_scene outliers 1000 tol outliers 2000 1000 1 4 15
    # Above 32768 particles a thread works through blocks of slices (the large-N path; K = 16).
    listed_scene fast_blocks 2400 none slow 34000 2400 1 2 16 350 700
    # The same path with outliers (every 100th), whose pairs also go through the prefetch
    # queue that grid uses only above 32768 particles. 330 outliers, more than the N / 128
    # that v_ref leaves faster than itself: v_ref (~4e3) is an outlier's speed, the 257
    # fastest are wide and the rest are binned, K ~ 40. Every 50th (660) passes the same
    # paths with v_ref ~6e4 and K ~ 560, and made grid test each pair twice a step: 14 times
    # this scene's work. One step: fast_blocks runs the large-N path over two.
    listed_scene outliers_blocks 3000 tol outliers 33000 3000 1 1 17 100
fi

# ---- random scenes (the binaries' generator: fast, L/8r .. L/4 per step) ----
random_scene empty 0 10 1 3 1
random_scene single 1 10 1 3 1
random_scene pair 2 4 1 5 2
if ((SMALL)); then
    random_scene report_like 400 4000 1 3 3
    random_scene dense_fast 200 100 1 3 4
    random_scene huge_L 200 1e7 1 3 5
    random_scene tiny_L 30 10 1 5 6
    random_scene big_r 100 50 2 4 7
else
    random_scene report_like 2000 2000 1 4 3
    random_scene dense_fast 1000 300 1 3 4
    random_scene huge_L 1000 1e7 1 3 5
    random_scene tiny_L 60 10 1 8 6
    random_scene big_r 500 50 2 4 7
    random_scene many_slices 4000 2000 0.5 2 8 none
fi

echo "$pass passed, $fail failed"
((fail == 0))
