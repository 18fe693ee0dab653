"""The variant registry: which variants exist and what each is, from the binaries themselves.

A variant is one file, variants/NAME.c; the Makefile builds every such file into build/NAME.
What a variant is comes from its own definition in C (`sim_variant_def`), which its binary
prints as one JSON line with `--describe`: whether its output is byte-identical to seq
(`exact`), whether it uses threads (`parallel`), whether it tests every pair i < j with seq's
kernel (`all_pairs`: its speedup over seq is parallelism alone), and which of the seed's
strategies it repairs (`repairs`). The harness, the C scene scripts and the report read these
facts and keep no list of their own, so a new variant needs no change anywhere else.

The order tables and figures show variants in follows from the facts: seq (the baseline)
first, then the all-pairs variants, then the others; within each, families by name, a
family being a variant followed by the variants that repair it.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import json
import subprocess
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path

from harness.errors import HarnessError
from harness.repo import BUILD_DIR, REPO_ROOT, VARIANTS_DIR
from harness.spec.builds import make_binaries

BASELINE = "seq"  # SPEC section 6: every variant is checked against it
GRID = "grid"  # byte-identical to seq and far faster: the reference where seq would take hours
DESCRIBE_OPTION = "--describe"
DESCRIBE_TIMEOUT_S = 10.0
FACT_TYPES: dict[str, tuple[type, ...]] = {
    "name": (str,), "summary": (str,), "exact": (bool,), "parallel": (bool,),
    "all_pairs": (bool,), "repairs": (str, type(None)),
}
# `sync`: the finder's OpenMP operations per step (variants/core/sim.h's sim_sync), or null.
# Optional: binaries of older commits (history, compare) print no such key.
SYNC_KEY = "sync"
SYNC_OPERATIONS = ("regions", "nested_regions", "barriers", "grabs")
COUNT_UNITS = ("step", "row", "pair", "tile")


@dataclass(frozen=True)
class Count:
    """How many of one operation a step asks for: step + row*N + pair*N(N-1)/2 + tile*(the
    tiles of `tile` j of every row)."""

    step: int = 0
    row: int = 0
    pair: int = 0
    tile: int = 0

    def per_step(self, n: int, tile: int) -> float:
        """The count in a step of N particles (rows i < N, pairs i < j, tiles of `tile` j)."""
        rows = n - 1  # row i has N-1-i pairs; the tiles of all rows: sum of ceil(m/tile), m < N
        tiles = 0.0
        if self.tile:
            q, r = divmod(rows, tile)
            tiles = tile * q * (q + 1) / 2 + r * (q + 1)
        return (self.step + self.row * n + self.pair * n * (n - 1) / 2
                + self.tile * tiles)


@dataclass(frozen=True)
class SyncFacts:
    """What a finder asks of the OpenMP runtime in a step: parallel regions (a team fork and
    its closing barrier), regions each thread of an outer team forks at once (T at a time),
    barriers inside regions, and chunks grabbed from a dynamic schedule's counter."""

    regions: Count = Count()
    nested_regions: Count = Count()
    barriers: Count = Count()
    grabs: Count = Count()
    tile: int = 0

    def per_step(self, n: int) -> dict[str, float]:
        """Each operation's count in a step of N particles."""
        return {op: getattr(self, op).per_step(n, self.tile) for op in SYNC_OPERATIONS}

    @classmethod
    def parse(cls, data: object, where: str) -> SyncFacts | None:
        """`--describe`'s sync object (None for null); a HarnessError naming `where`."""
        if data is None:
            return None
        wrong = f"{where}: {DESCRIBE_OPTION}'s '{SYNC_KEY}' is {data!r}"
        if not isinstance(data, dict) or set(data) != {*SYNC_OPERATIONS, "tile"}:
            raise HarnessError(f"{wrong}, expected an object of {', '.join(SYNC_OPERATIONS)} "
                               "and tile")
        counts = {}
        for op in SYNC_OPERATIONS:
            terms = data[op]
            if not (isinstance(terms, dict) and set(terms) <= set(COUNT_UNITS) and all(
                    _natural(v) for v in terms.values())):
                raise HarnessError(f"{wrong}: '{op}' is no object of counts per "
                                   f"{', '.join(COUNT_UNITS)}")
            counts[op] = Count(**terms)
        tile = data["tile"]
        per_tile = any(c.tile for c in counts.values())
        if not _natural(tile) or (per_tile and tile < 1):
            raise HarnessError(f"{wrong}: 'tile' must be a count, at least 1 where a count is "
                               "per tile")
        return cls(**counts, tile=tile)


def _natural(value: object) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and value >= 0


@dataclass(frozen=True)
class VariantFacts:
    """What a variant's binary says it is (`--describe`)."""

    name: str
    summary: str
    exact: bool
    parallel: bool
    all_pairs: bool
    repairs: str | None = None
    sync: SyncFacts | None = None  # None: not declared (depends on the data or OMP_SCHEDULE)

    @classmethod
    def parse(cls, text: str, where: str) -> VariantFacts:
        """One `--describe` line; a HarnessError naming `where` when it is not one."""
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise HarnessError(f"{where}: {DESCRIBE_OPTION} printed no JSON object: "
                               f"{exc}") from None
        if not isinstance(data, dict):
            raise HarnessError(f"{where}: {DESCRIBE_OPTION} printed no JSON object")
        for key, types in FACT_TYPES.items():
            if key not in data:
                raise HarnessError(f"{where}: {DESCRIBE_OPTION} lacks '{key}'")
            if not isinstance(data[key], types):
                raise HarnessError(f"{where}: {DESCRIBE_OPTION}'s '{key}' is "
                                   f"{data[key]!r}, not of the expected type")
        return cls(**{key: data[key] for key in FACT_TYPES},
                   sync=SyncFacts.parse(data.get(SYNC_KEY), where))


def family_of(facts: Mapping[str, VariantFacts], name: str) -> str:
    """The variant a family is named after: the one `name` repairs, where it exists."""
    repairs = facts[name].repairs
    return repairs if repairs is not None and repairs in facts else name


def ordered(facts: Mapping[str, VariantFacts]) -> tuple[str, ...]:
    """The variants in the order tables show them (the module docstring says which)."""
    def family_key(root: str) -> tuple[int, str]:
        group = 0 if root == BASELINE else 1 if facts[root].all_pairs else 2
        return group, root

    roots = sorted({family_of(facts, n) for n in facts}, key=family_key)
    order: list[str] = []
    for root in roots:
        order.append(root)
        order += sorted(n for n in facts if n != root and family_of(facts, n) == root)
    return tuple(order)


class VariantRegistry:
    """The variants of a repository: names from variants/*.c, facts from build/NAME
    --describe (built with make when missing or out of date)."""

    def __init__(self, repo_root: Path = REPO_ROOT, make: str = "make",
                 facts: Iterable[VariantFacts] | None = None) -> None:
        self.repo_root = repo_root
        self.make = make
        self._given = None if facts is None else {f.name: f for f in facts}

    @classmethod
    def of(cls, facts: Iterable[VariantFacts]) -> VariantRegistry:
        """A registry of the given facts, reading no binary (tests, other repositories)."""
        return cls(facts=facts)

    @functools.cached_property
    def names(self) -> tuple[str, ...]:
        """The variants, baseline first, then by name; no binary is needed for them."""
        if self._given is not None:
            found = set(self._given)
        else:
            found = {p.stem for p in (self.repo_root / VARIANTS_DIR).glob("*.c")}
        return tuple(sorted(found, key=lambda n: (n != BASELINE, n)))

    def __contains__(self, name: object) -> bool:
        return name in self.names

    def binary(self, name: str) -> Path:
        return self.repo_root / BUILD_DIR / name

    @functools.cached_property
    def facts(self) -> dict[str, VariantFacts]:
        """Every variant's facts, by name (builds the binaries that make says are stale)."""
        if self._given is not None:
            return dict(self._given)
        binaries = [self.binary(n) for n in self.names]
        make_binaries(self.repo_root, binaries, self.make, capture=True)
        return {name: describe(self.binary(name)) for name in self.names}

    def __getitem__(self, name: str) -> VariantFacts:
        try:
            return self.facts[name]
        except KeyError:
            raise HarnessError(f"unknown variant {name!r}; expected one of: "
                               f"{', '.join(self.names)}") from None

    @functools.cached_property
    def order(self) -> tuple[str, ...]:
        return ordered(self.facts)

    def get(self, name: str) -> VariantFacts | None:
        """A variant's facts; None for a name that is no variant of the repository (a custom
        binary, results of a variant since removed)."""
        return self.facts.get(name)

    def rank(self, name: str) -> int:
        """A variant's position in `order`; after every known variant for any other name."""
        return self._ranks.get(name, len(self._ranks))

    @functools.cached_property
    def _ranks(self) -> dict[str, int]:
        return {name: k for k, name in enumerate(self.order)}

    @functools.cached_property
    def families(self) -> tuple[str, ...]:
        """The variants that name a family (those repaired, and those that repair nothing),
        in order: a figure gives each its own colour, and a repair its family's."""
        return tuple(n for n in self.order if family_of(self.facts, n) == n)

    def family(self, name: str) -> str:
        return family_of(self.facts, name) if name in self.facts else name

    def repaired_by(self, name: str) -> tuple[str, ...]:
        """The variants that repair `name`, in order."""
        return tuple(n for n in self.order if self.facts[n].repairs == name)

    def digest(self) -> str:
        """The facts as canonical JSON, for caches keyed on them."""
        return json.dumps([dataclasses.asdict(self.facts[n]) for n in self.order],
                          sort_keys=True)


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
    facts = VariantFacts.parse(done.stdout.strip(), f"{binary}")
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
    """default_registry() answers with `registry` inside the block."""
    default_registry()
    _default.append(registry)
    try:
        yield registry
    finally:
        _default.remove(registry)
