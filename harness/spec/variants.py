"""The variant registry: which variants exist and what each is, from the binaries themselves,
and the one place the spec runs make (whoever only reads results never imports this module).
A variant is one file, variants/NAME.c, built into build/NAME where the Makefile can (`make
print-variants`); its binary's `--describe` says what it is, so the harness keeps no list of
its own, and a new variant needs no change anywhere else.
"""

import contextlib
import functools
import json
import subprocess
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path

from harness.errors import HarnessError
from harness.repo import BUILD_DIR, REPO_ROOT, VARIANTS_DIR
from harness.spec.facts import BASELINE, DESCRIBE_OPTION, VariantFacts, Variants

DESCRIBE_TIMEOUT_S = 10.0


class VariantRegistry:
    """The variants of a repository: names from variants/*.c, facts from build/NAME
    --describe (built with make when missing or out of date), or the `facts` given."""

    def __init__(self, repo_root: Path = REPO_ROOT,
                 facts: Iterable[VariantFacts] | None = None) -> None:
        self.repo_root = repo_root
        self._given = None if facts is None else {f.name: f for f in facts}

    @functools.cached_property
    def sources(self) -> frozenset[str]:
        """Every variant with a source, variants/NAME.c, whether or not it builds here."""
        if self._given is not None:
            return frozenset(self._given)
        return frozenset(p.stem for p in (self.repo_root / VARIANTS_DIR).glob("*.c"))

    @functools.cached_property
    def names(self) -> tuple[str, ...]:
        """The variants this machine builds (the Makefile's list; every source in a repository
        whose Makefile has none), baseline first, then by name; no binary is needed."""
        found = set(self.sources) if self._given is not None else self._buildable()
        return tuple(sorted(found, key=lambda n: (n != BASELINE, n)))

    @property
    def unbuilt(self) -> frozenset[str]:
        """The variants with a source that the Makefile leaves out here (an MPI variant on a
        machine without mpicc)."""
        return self.sources - set(self.names)

    def _buildable(self) -> set[str]:
        try:
            listed = subprocess.run(["make", "-s", "--no-print-directory", "print-variants"],
                                    cwd=self.repo_root, capture_output=True, text=True,
                                    check=False, timeout=60)
        except (OSError, subprocess.TimeoutExpired):
            return set(self.sources)
        names = set(listed.stdout.split())
        return names & self.sources if listed.returncode == 0 and names else set(self.sources)

    def __contains__(self, name: object) -> bool:
        return name in self.names

    @functools.cached_property
    def known(self) -> Variants:
        """Every variant's facts, ordered (builds the binaries that make says are stale)."""
        if self._given is not None:
            return Variants.of(self._given.values())
        binaries = [self.repo_root / BUILD_DIR / name for name in self.names]
        make_binaries(self.repo_root, binaries, capture=True)
        return Variants.of(describe(binary) for binary in binaries)

    def __getitem__(self, name: str) -> VariantFacts:
        return self.known[name]

    def get(self, name: str) -> VariantFacts | None:
        return self.known.get(name)


def describe(binary: Path) -> VariantFacts:
    """`binary --describe`, parsed; a HarnessError when it cannot run or says no JSON."""
    try:
        done = subprocess.run([str(binary), DESCRIBE_OPTION], capture_output=True, text=True,
                              timeout=DESCRIBE_TIMEOUT_S, check=False,
                              stdin=subprocess.DEVNULL)
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise HarnessError(f"{binary}: cannot run {DESCRIBE_OPTION}: {exc}") from None
    if done.returncode != 0:
        detail = done.stderr.strip()[-300:]
        raise HarnessError(f"{binary} {DESCRIBE_OPTION} failed (exit {done.returncode})"
                           + (f": {detail}" if detail else ""))
    try:
        facts = VariantFacts.from_json(json.loads(done.stdout.strip()), f"{binary}")
    except json.JSONDecodeError as exc:
        raise HarnessError(f"{binary}: {DESCRIBE_OPTION} printed no JSON object: {exc}") from None
    if facts.name != binary.name:
        raise HarnessError(f"{binary}: {DESCRIBE_OPTION} names the variant {facts.name!r}")
    return facts


_default: list[VariantRegistry] = []  # the registry default_registry() answers with, once made


def default_registry() -> VariantRegistry:
    """The registry of this repository, made once per process; `using` replaces it for a
    while (tests, a copy of the repository)."""
    if not _default:
        _default.append(VariantRegistry())
    return _default[-1]


@contextlib.contextmanager
def using(registry: VariantRegistry) -> Iterator[VariantRegistry]:
    default_registry()
    _default.append(registry)
    try:
        yield registry
    finally:
        _default.remove(registry)


def make_binaries(repo_root: Path, binaries: Iterable[Path], make: str = "make",
                  capture: bool = False, extra: Sequence[str] = ()) -> None:
    """One `make -s [EXTRA] build/a build/b ...` call (nothing when the list is empty); a
    failure is a HarnessError. With `capture`, make's output goes into the error only."""
    targets = [str(b.relative_to(repo_root)) for b in binaries]
    if not targets:
        return
    done = _make(repo_root, make, ["-s", *extra, *targets], capture)
    if done.returncode != 0:
        detail = f": {' '.join(done.stderr.split())[-500:]}" if capture and done.stderr else ""
        raise HarnessError(f"make -s {' '.join([*extra, *targets])} failed with exit status "
                           f"{done.returncode}{detail}")


def has_rules(repo_root: Path, binaries: Iterable[Path]) -> bool:
    """Whether the Makefile in `repo_root` can make every one of `binaries`: `make -n` (a dry
    run, nothing built) finds a rule for each and for what each is made of."""
    targets = [str(b.relative_to(repo_root)) for b in binaries]
    return _make(repo_root, "make", ["-n", "-s", *targets], capture=True).returncode == 0


def _make(repo_root: Path, make: str, args: Sequence[str],
          capture: bool) -> subprocess.CompletedProcess[str]:
    try:
        return subprocess.run([make, *args], cwd=repo_root, check=False, text=True,
                              errors="replace", stdin=subprocess.DEVNULL,
                              capture_output=capture)
    except OSError as exc:
        raise HarnessError(f"cannot run {make}: {exc.strerror}") from None
