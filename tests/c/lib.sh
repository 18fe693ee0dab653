# lib.sh BUILD_DIR: what the scene scripts share, sourced after `set -euo pipefail`:
#
#   B           the build directory under test (build, build/asan, build/portable)
#   HERE, ROOT  tests/c and the repository
#   TMP         a scratch directory, removed on exit
#   ok, bad WHAT     count a passed check, or a failed one with its FAIL line
#   finish           print `N passed, M failed`; its status is nonzero when anything failed
#   print_variants   the variants the Makefile builds (make print-variants)
#   part NAME        start timing a part of the script (part alone: the last one's time)
#   scene_args, strip_zeros, json_field, slow_scene, lattice_scene: below
#
# A wrong command line is the usage on stderr and status 2. The runs do not depend on the
# caller's OpenMP settings (a check that needs one sets it itself).

if [ $# -ne 1 ]; then
    echo "usage: $0 BUILD_DIR" >&2
    exit 2
fi
B=$1
HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
ROOT=$(cd "$HERE/../.." && pwd)
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
# Open MPI keeps a job's session directory under one /tmp/ompi.HOST.UID that every job of the
# machine shares; a job that ends removes parts of it while another script's job (the scripts
# run side by side) creates its own there. Each script's jobs keep theirs under its own TMP.
export OMPI_MCA_orte_tmpdir_base="$TMP"
unset OMP_NUM_THREADS OMP_SCHEDULE OMP_DYNAMIC OMP_MAX_ACTIVE_LEVELS || true

pass=0
fail=0
ok() { pass=$((pass + 1)); }
bad() {
    fail=$((fail + 1))
    echo "FAIL: $*"
}

finish() {
    echo "$pass passed, $fail failed"
    [ "$fail" = 0 ]
}

# Without the caller's MAKEFLAGS: under `make test-c` they name a jobserver this make cannot use.
print_variants() {
    MAKEFLAGS= MAKELEVEL= make -s --no-print-directory -C "$ROOT" print-variants
}

# Each part of a script prints its time when the next one starts (`part` with no name: the last).
part_start=0
part() {
    local now
    now=$(date +%s%N)
    if [ "$part_start" != 0 ]; then
        printf '# %-28s %6.2f s\n' "$part_name" "$(((now - part_start) / 1000000))e-3"
    fi
    part_name=${1:-}
    part_start=$now
}

# scene_args SCENE.in: the scene's own arguments (SCENE.args beside it, e.g. `--seed 42`; none
# where there is no such file) into the array args.
scene_args() {
    args=()
    if [ -f "${1%.in}.args" ]; then
        read -r -a args <"${1%.in}.args" || true
    fi
}

# The %.17g text of a %.8f expectation whose values are exact in binary with at most 8
# decimals: %.8f with the trailing zeros (and a bare point) removed.
strip_zeros() {
    awk '{ for (k = 3; k <= 6 && k <= NF; k++) { if ($k ~ /\./) { sub(/0+$/, "", $k); sub(/\.$/, "", $k) } } print }' "$1"
}

# json_field NAME FILE: the value of "NAME": in a one-line JSON object (FILE - for stdin).
json_field() {
    sed -n 's/.*"'"$1"'": *"\{0,1\}\([^,"}]*\)"\{0,1\}[,}].*/\1/p' "$2"
}

# Random scenes. Generated ones ("N L r S" and a mode, particles from --seed) move fast: speeds
# between L/(8r) and L/4 per step. Slow ones list their particles, drawn by this awk script
# with its own Lehmer generator (exact in doubles, so every awk draws the same scene):
#   slow_scene N L r S MODE SEED VMAX [EVERY]: speeds up to VMAX per step on each axis;
#   with EVERY > 1 only every EVERY-th particle is listed and the rest are generated.
slow_scene() {
    awk -v n="$1" -v L="$2" -v r="$3" -v S="$4" -v mode="$5" -v s="$6" -v vmax="$7" -v every="${8:-1}" '
        function rnd() { s = (s * 16807) % 2147483647; return s / 2147483647 }
        function coord(  q) { q = r + rnd() * (L - 2 * r); return q > L - r ? L - r : q }
        BEGIN {
            print n, L, r, S; print mode
            for (i = 0; i < n; i++) {
                x = coord(); y = coord(); vx = vmax * (2 * rnd() - 1); vy = vmax * (2 * rnd() - 1)
                if (i % every == 0) printf "%d %.17g %.17g %.17g %.17g\n", i, x, y, vx, vy
            }
        }'
}
# lattice_scene K SPACING S MODE SEED: K*K discs (r = 1) on a square lattice, velocities in
# multiples of 1/4 up to 1: with SPACING 2 every neighbour touches (c == 0), so many contact
# times are exactly equal and the tie-break decides.
lattice_scene() {
    awk -v k="$1" -v d="$2" -v S="$3" -v mode="$4" -v s="$5" '
        function rnd() { s = (s * 16807) % 2147483647; return s / 2147483647 }
        BEGIN {
            L = 2 + d * (k - 1) + 2; print k * k, L, 1, S; print mode
            for (i = 0; i < k * k; i++)
                printf "%d %.17g %.17g %.17g %.17g\n", i, 2 + d * (i % k), 2 + d * int(i / k), int(9 * rnd() - 4.5) / 4, int(9 * rnd() - 4.5) / 4
        }'
}
