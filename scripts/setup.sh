#!/usr/bin/env bash
# Set up what collide-bench needs beyond gcc, make and python3: the Python environment
# (.venv, pinned requirements.txt) and hyperfine (Debian's package). Used by `make setup` and
# the quick start.
#
# With --test, also what only the tests need: the pinned requirements-test.txt (pytest, ruff,
# import-linter, selenium) and, as root, Debian's Slurm (slurmctld, slurmd, slurm-client, munge)
# for the Slurm executor's tests, Debian's chromium and chromium-driver for the report's
# browser test, clang with its ThreadSanitizer runtime and LLVM's OpenMP with Archer
# (clang, libclang-rt-dev, libomp-dev) for the data-race check of programs, and Open MPI
# (openmpi-bin, libopenmpi-dev: mpicc and mpirun), with which `make all` builds the mpi variant
# and tests/c/mpi_scenes.sh runs it. Used by `make test` (through `make setup-test`) and CI.
#
# With configs (scripts/setup.sh [--test] CONFIG...): also what they ask for; a config with
# `metric: instructions` needs an instruction counter, and where the kernel gives no hardware
# counters that is Valgrind's cachegrind (Debian's valgrind; --test installs it too, for the
# instruction lane's tests).
#
# Safe to run again: it does only what is missing.
set -euo pipefail
cd "$(dirname "$0")/.."

test_too=false
lane=false
for arg in "$@"; do
    case "$arg" in
        --test) test_too=true; lane=true ;;
        -*) echo "usage: scripts/setup.sh [--test] [CONFIG...]" >&2; exit 2 ;;
        *)
            if [ ! -f "$arg" ]; then echo "setup: config not found: $arg" >&2; exit 2; fi
            if grep -Eq '^metric:[[:space:]]*instructions' "$arg"; then lane=true; fi ;;
    esac
done

venv=.venv
stamp=$venv/.requirements.sha256
want=$(cat requirements.txt pyproject.toml | sha256sum | cut -d' ' -f1)
test_stamp=$venv/.requirements-test.sha256
test_want=$(cat requirements-test.txt | sha256sum | cut -d' ' -f1)

as_root() { [ "$(id -u)" = 0 ]; }
apt_install() {
    # apt-get update only when a package is unknown to the local lists.
    local pkg
    for pkg in "$@"; do
        if ! apt-cache show "$pkg" >/dev/null 2>&1; then apt-get update -q >/dev/null; break; fi
    done
    DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends "$@" >/dev/null
}

# Python environment.
if [ ! -x "$venv/bin/python" ]; then
    if ! python3 -m venv "$venv" 2>/dev/null; then
        rm -rf "$venv"
        if as_root; then
            apt_install python3-venv
            python3 -m venv "$venv"
        else
            echo "setup: python3 cannot create a virtual environment; run: sudo apt-get install python3-venv" >&2
            exit 1
        fi
    fi
fi
if [ -L "$venv" ]; then
    # A .venv linked from another checkout (the README's test runs in a copy) is that
    # checkout's: its editable install stays pointed there.
    :
elif [ "$(cat "$stamp" 2>/dev/null)" != "$want" ]; then
    echo "setup: installing Python packages into $venv (requirements.txt)"
    "$venv/bin/python" -m pip install -q --disable-pip-version-check -r requirements.txt
    # The harness itself, editable: `import harness` and the collide-bench command from any
    # directory, with the sources of this checkout.
    "$venv/bin/python" -m pip install -q --disable-pip-version-check --no-deps \
        --no-build-isolation -e .
    echo "$want" > "$stamp"
fi

# hyperfine.
if ! command -v hyperfine >/dev/null 2>&1; then
    if as_root && command -v apt-get >/dev/null 2>&1; then
        echo "setup: installing hyperfine (Debian package)"
        apt_install hyperfine
    else
        echo "setup: hyperfine is missing; run: sudo apt-get install hyperfine" >&2
        exit 1
    fi
fi

# The instruction lane's counter where hardware counters are missing (a VM): cachegrind.
if $lane && ! command -v valgrind >/dev/null 2>&1 \
        && ! perf stat -x, -e instructions:u true 2>&1 | grep -Eq '^[0-9]+,'; then
    if as_root && command -v apt-get >/dev/null 2>&1; then
        echo "setup: installing valgrind (Debian package), the instruction lane's counter"
        apt_install valgrind
    else
        echo "setup: the instruction lane needs valgrind; run: sudo apt-get install valgrind" >&2
        $test_too || exit 1
    fi
fi
if ! $test_too; then
    echo "setup: ready ($("$venv/bin/python" --version), $(hyperfine --version))"
    exit 0
fi

# What only the tests need.
if [ "$(cat "$test_stamp" 2>/dev/null)" != "$test_want" ]; then
    echo "setup: installing the test tools into $venv (requirements-test.txt)"
    "$venv/bin/python" -m pip install -q --disable-pip-version-check -r requirements-test.txt
    echo "$test_want" > "$test_stamp"
fi
# Debian packages the tests use where they can; without root they skip and say why (and fail
# under CI).
optional_packages() {  # WHAT, a command each package set provides..., --, packages...
    local what=$1 missing=false; shift
    while [ "$1" != -- ]; do command -v "$1" >/dev/null 2>&1 || missing=true; shift; done
    shift
    $missing || return 0
    if as_root && command -v apt-get >/dev/null 2>&1; then
        echo "setup: installing $what (Debian packages: $*)"
        apt_install "$@"
    else
        echo "setup: $what is missing (its tests will skip); to run them: sudo apt-get install $*" >&2
    fi
}
# Slurm, for tests/executors/test_slurm.py (a single-node cluster started by the tests
# themselves; no daemon is started here).
optional_packages Slurm slurmctld slurmd sbatch munged -- slurmctld slurmd slurm-client munge
# A browser, for tests/report/test_browser.py (selenium drives Debian's chromium headless).
optional_packages chromium chromium chromedriver -- chromium chromium-driver
# Open MPI, for the mpi variant (make all builds it where mpicc is) and tests/c/mpi_scenes.sh.
optional_packages "Open MPI" mpicc mpirun -- openmpi-bin libopenmpi-dev
# clang's ThreadSanitizer with LLVM's OpenMP runtime and Archer, for tests/programs/test_races.py
# and the data-race check of programs with a build (harness/measure/races.py): packages, not
# commands, since clang alone links no TSan runtime.
tsan_packages=(clang libclang-rt-dev libomp-dev)
if [ "$(dpkg-query -W -f='${Status}\n' "${tsan_packages[@]}" 2>/dev/null \
        | grep -c 'install ok installed')" != "${#tsan_packages[@]}" ]; then
    if as_root && command -v apt-get >/dev/null 2>&1; then
        echo "setup: installing clang's ThreadSanitizer and Archer (Debian packages: ${tsan_packages[*]})"
        apt_install "${tsan_packages[@]}"
    else
        echo "setup: clang's ThreadSanitizer is missing (its tests will skip); to run them: sudo apt-get install ${tsan_packages[*]}" >&2
    fi
fi
touch "$venv/.test-ready"  # make test's stamp (the Makefile's TEST_READY)
echo "setup: ready for the tests ($("$venv/bin/python" --version), $(hyperfine --version))"
