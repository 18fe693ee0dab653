"""What each variant is (its binary's `--describe`, docs/variants.md): typed, checked, and
stored with the results it measured (variants.json), so that whoever reads results needs no
binary, no build and no make. `exact`: byte-identical to seq; `parallel`: uses threads;
`all_pairs`: tests every pair i < j with seq's kernel, so its speedup over seq is parallelism
alone; `repairs`: the seed's strategy it repairs. harness.spec.variants asks the binaries; this
module only parses, orders and serialises."""

from __future__ import annotations

import functools
import json
from collections import Counter
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path

from harness.errors import HarnessError

BASELINE = "seq"  # SPEC section 6: every variant is checked against it
GRID = "grid"  # byte-identical to seq and far faster: the reference where seq would take hours
DESCRIBE_OPTION = "--describe"
FACT_TYPES: dict[str, tuple[type, ...]] = {
    "name": (str,), "summary": (str,), "exact": (bool,), "parallel": (bool,),
    "all_pairs": (bool,), "repairs": (str, type(None)),
}
# `sync`: the finder's OpenMP operations per step (variants/core/sim.h's sim_sync), or null.
# Optional: binaries of older commits (history, compare) print no such key.
SYNC_KEY = "sync"
# `mpi`: the variant runs as MPI ranks. Optional: binaries from before MPI print no such key.
MPI_KEY = "mpi"
SYNC_OPERATIONS = ("regions", "nested_regions", "barriers", "grabs")
COUNT_UNITS = ("step", "row", "pair", "tile")
VARIANTS_KEY = "variants"  # variants.json: {"variants": [one --describe object a variant]}


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
        # row i has N-1-i pairs; the tiles of all rows: sum of ceil(m/tile), m < N
        q, r = divmod(n - 1, tile) if self.tile else (0, 0)
        tiles = tile * q * (q + 1) / 2 + r * (q + 1)
        return self.step + self.row * n + self.pair * n * (n - 1) / 2 + self.tile * tiles

    def to_json(self) -> dict[str, int]:
        """The terms as `--describe` prints them: only those that are not zero."""
        return {unit: getattr(self, unit) for unit in COUNT_UNITS if getattr(self, unit)}


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
        return {op: getattr(self, op).per_step(n, self.tile) for op in SYNC_OPERATIONS}

    def to_json(self) -> dict[str, object]:
        return {**{op: getattr(self, op).to_json() for op in SYNC_OPERATIONS}, "tile": self.tile}

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
        if not _natural(tile) or (tile < 1 and any(c.tile for c in counts.values())):
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
    mpi: bool = False  # runs as MPI ranks (under mpirun); older binaries do not say: False

    @classmethod
    def from_json(cls, data: object, where: str) -> VariantFacts:
        """One `--describe` object; a HarnessError naming `where` when it is not one."""
        if not isinstance(data, dict):
            raise HarnessError(f"{where}: {DESCRIBE_OPTION} printed no JSON object")
        for key, types in {**FACT_TYPES, MPI_KEY: (bool,)}.items():
            if key not in data and key != MPI_KEY:
                raise HarnessError(f"{where}: {DESCRIBE_OPTION} lacks '{key}'")
            if not isinstance(data.get(key, False), types):
                raise HarnessError(f"{where}: {DESCRIBE_OPTION}'s '{key}' is "
                                   f"{data[key]!r}, not of the expected type")
        return cls(**{key: data[key] for key in FACT_TYPES},
                   sync=SyncFacts.parse(data.get(SYNC_KEY), where), mpi=data.get(MPI_KEY, False))

    def to_json(self) -> dict[str, object]:
        """The facts as `--describe` prints them."""
        return {**{key: getattr(self, key) for key in FACT_TYPES}, MPI_KEY: self.mpi,
                SYNC_KEY: None if self.sync is None else self.sync.to_json()}


@dataclass(frozen=True)
class IgnoredAxis:
    """An axis of a config's grid that a variant's facts can say it ignores: its cells along
    the axis are then one cell, run at `value`, so its records at `value` keep their ids."""

    field: str  # the name of the axis in a cell, its key and its record
    value: object
    uses: Callable[[VariantFacts], bool]  # whether a variant of these facts uses the axis


# How a machine gets Open MPI (mpicc for an MPI variant's build, mpirun for its cells): Debian's.
MPI_INSTALL = "sudo apt-get install openmpi-bin libopenmpi-dev"
# A variant ignores threads where its --describe says "parallel": false, ranks where it does
# not say "mpi": true.
RANKS_AXIS = IgnoredAxis("ranks", 1, lambda f: f.mpi)
IGNORED_AXES: tuple[IgnoredAxis, ...] = (IgnoredAxis("threads", 1, lambda f: f.parallel),
                                         RANKS_AXIS)


def ignored_axes(facts: VariantFacts) -> list[IgnoredAxis]:
    return [axis for axis in IGNORED_AXES if not axis.uses(facts)]


@dataclass(frozen=True)
class Variants:
    """The facts of a set of variants (a repository's build, or the one results were measured
    with): their order, their families and who repairs whom."""

    members: tuple[VariantFacts, ...] = ()

    @classmethod
    def of(cls, facts: Iterable[VariantFacts]) -> Variants:
        return cls(tuple(sorted(facts, key=lambda f: f.name)))

    @functools.cached_property
    def by_name(self) -> dict[str, VariantFacts]:
        return {f.name: f for f in self.members}

    def __contains__(self, name: object) -> bool:
        return name in self.by_name

    def __getitem__(self, name: str) -> VariantFacts:
        try:
            return self.by_name[name]
        except KeyError:
            raise HarnessError(f"unknown variant {name!r}; expected one of: "
                               f"{', '.join(self.order)}") from None

    def get(self, name: str) -> VariantFacts | None:
        """A variant's facts; None for a custom binary, or a variant since removed."""
        return self.by_name.get(name)

    def family(self, name: str) -> str:
        """The variant a family is named after: the one `name` repairs, where it is a member."""
        repairs = getattr(self.by_name.get(name), "repairs", None)
        return repairs if repairs in self.by_name else name

    @functools.cached_property
    def order(self) -> tuple[str, ...]:
        """The order tables and figures show variants in: seq (the baseline) first, then the
        all-pairs variants, then the others; within each, families by name, a family being a
        variant followed by the variants that repair it."""
        roots = sorted({self.family(n) for n in self.by_name},
                       key=lambda root: (root != BASELINE, not self[root].all_pairs, root))
        return tuple(n for root in roots for n in (
            root, *sorted(n for n in self.by_name if n != root and self.family(n) == root)))

    @functools.cached_property
    def families(self) -> tuple[str, ...]:
        """The variants that name a family (those repaired, and those that repair nothing),
        in order: a figure gives each its own colour, and a repair its family's."""
        return tuple(n for n in self.order if self.family(n) == n)

    def repaired_by(self, name: str) -> tuple[str, ...]:
        return tuple(n for n in self.order if self.by_name[n].repairs == name)

    def to_json(self) -> dict[str, object]:
        """variants.json's content: the facts in order."""
        return {VARIANTS_KEY: [self.by_name[n].to_json() for n in self.order]}

    def digest(self) -> str:
        """The facts as canonical JSON, for caches keyed on them."""
        return json.dumps(self.to_json(), sort_keys=True)

    @classmethod
    def from_json(cls, data: object, where: str) -> Variants:
        """variants.json's content; a HarnessError naming `where` and what is wrong."""
        if not isinstance(data, dict) or not isinstance(data.get(VARIANTS_KEY), list):
            raise HarnessError(f"{where}: expected an object with a list '{VARIANTS_KEY}'")
        members = [VariantFacts.from_json(item, f"{where}: {VARIANTS_KEY}[{k}]")
                   for k, item in enumerate(data[VARIANTS_KEY])]
        twice = sorted(n for n, k in Counter(f.name for f in members).items() if k > 1)
        if twice:
            raise HarnessError(f"{where}: variant(s) listed twice: {', '.join(twice)}")
        return cls.of(members)


def read_variants(path: Path) -> Variants:
    """A result set's variants.json; no facts where it is absent (results measured before
    they were stored: every variant unknown). A HarnessError naming the file otherwise."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        return NO_FACTS
    except json.JSONDecodeError as exc:
        raise HarnessError(f"{path}: not JSON: {exc}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise HarnessError(f"{path}: cannot read the variants' facts: {exc}") from None
    return Variants.from_json(data, str(path))


NO_FACTS = Variants()
