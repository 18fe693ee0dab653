#!/usr/bin/env bash
# Set up what collide-bench needs beyond gcc, make and python3: the Python environment
# (.venv, pinned requirements.txt), hyperfine (Debian's package) and, as root, Debian's Slurm
# (slurmctld, slurmd, slurm-client, munge) for the Slurm executor's tests. Safe to run again: it does
# only what is missing. Used by `make setup`, the quick start and CI.
set -euo pipefail
cd "$(dirname "$0")/.."

venv=.venv
stamp=$venv/.requirements.sha256
want=$(cat requirements.txt pyproject.toml | sha256sum | cut -d' ' -f1)

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
if [ "$(cat "$stamp" 2>/dev/null)" != "$want" ]; then
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
# Slurm, for tests/test_slurm.py (a single-node cluster started by the tests themselves; no
# daemon is started here). Optional: without root the Slurm tests skip and say why.
slurm_pkgs=(slurmctld slurmd slurm-client munge)
if ! command -v slurmctld >/dev/null 2>&1 || ! command -v slurmd >/dev/null 2>&1 \
        || ! command -v sbatch >/dev/null 2>&1 || ! command -v munged >/dev/null 2>&1; then
    if as_root && command -v apt-get >/dev/null 2>&1; then
        echo "setup: installing Slurm (Debian packages: ${slurm_pkgs[*]})"
        apt_install "${slurm_pkgs[@]}"
    else
        echo "setup: Slurm is missing (the Slurm tests will skip); to run them: sudo apt-get install ${slurm_pkgs[*]}" >&2
    fi
fi
echo "setup: ready ($("$venv/bin/python" --version), $(hyperfine --version))"
