# lib.sh BUILD_DIR: what the scene scripts share, sourced after `set -euo pipefail`:
#
#   B           the build directory under test (build, build/asan, build/portable)
#   HERE, ROOT  tests/c and the repository
#   TMP         a scratch directory, removed on exit
#   ok, bad WHAT     count a passed check, or a failed one with its FAIL line
#   finish           print `N passed, M failed`; its status is nonzero when anything failed
#   print_variants   the variants the Makefile builds (make print-variants)
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
