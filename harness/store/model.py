"""A cell's key, typed: what was measured, how, with which binaries, on which machine.

Each field declares its role, and every name a record is known by is a projection of those
declarations (pyperf's explicit list of the metadata that must agree before runs are grouped):

- `id`, the content address a record is stored under: every field;
- `portable_id`: every field but the machine (what a Slurm submitter names a cell by);
- `group`: what ran and how its runs were taken (one current record per machine and group);
  whether instructions were counted, not with which counter;
- `timed_group`: what ran only: every record, of any machine, that timed the same cell.

A key reads back the JSON object it was written as, field for field, so the ids of stored
records never change. Standard library only.
"""

from __future__ import annotations

import enum
import functools
import hashlib
import json
import types
import typing
from collections.abc import Mapping
from dataclasses import dataclass, field, fields, is_dataclass

# The version hashed into every id: the ids of stored records depend on it, so it stays.
ID_VERSION = 1
ID_CHARS = 16


class Role(enum.Enum):
    WHAT = "what"  # what ran on what: in every projection
    HOW = "how"  # how the runs were taken (a config's `measure:`): not in the timed group
    BINARY = "binary"  # a binary's hash, built per machine: in the ids only
    MACHINE = "machine"  # the machine that measured: in the id only
    BESIDE = "beside"  # measured beside the runs, not in them: in the ids only
    COUNTED = "counted"  # instructions counted: the group keeps whether, the timed group not


class KeyFormatError(ValueError):
    """A stored key that is not a cell key of this harness."""


# Per projection, the roles it keeps, each with whether it keeps only that the field is there;
# a role not named is left out.
_PROJECTIONS: dict[str, dict[Role, bool]] = {
    "id": dict.fromkeys(Role, False),
    "portable": {role: False for role in Role if role is not Role.MACHINE},
    "group": {Role.WHAT: False, Role.HOW: False, Role.COUNTED: True},
    "timed": {Role.WHAT: False},
}


def content_id(value: Mapping[str, object]) -> str:
    """A content address: the same value gives the same id, any change a new one."""
    canonical = json.dumps({"version": ID_VERSION, **value}, sort_keys=True,
                           separators=(",", ":"))
    return hashlib.sha256(canonical.encode()).hexdigest()[:ID_CHARS]


def _role(role: Role, optional: bool = False) -> dict[str, object]:
    """A key field's declaration: its role; an optional field is left out of the JSON while
    None (keys without it keep their ids)."""
    return {"role": role, "optional": optional}


_optional = functools.partial(_role, optional=True)


@dataclass(frozen=True)
class TextMap:
    """Names to text: binaries' hashes by name (a check's or a program's references), or the
    OMP_PROC_BIND / OMP_PLACES a config sets for every cell."""

    items: tuple[tuple[str, str], ...]

    def to_json(self) -> dict[str, object]:
        return dict(self.items)

    @classmethod
    def from_json(cls, raw: object, where: str) -> TextMap:
        mapping = _mapping(raw, where)
        return cls(tuple((str(k), typed(v, str, f"{where}.{k}")) for k, v in mapping.items()))


@dataclass(frozen=True)
class ChecksKey:
    """What a checked cell's accuracy and stability checks depend on."""

    names: tuple[str, ...] = field(metadata=_role(Role.WHAT))
    truth: str = field(metadata=_role(Role.WHAT))
    shadow_steps: int = field(metadata=_role(Role.WHAT))
    energy_ulps: float = field(metadata=_role(Role.WHAT))
    shadow_ulps: float = field(metadata=_role(Role.WHAT))
    thread_counts: tuple[int, ...] = field(metadata=_role(Role.WHAT))
    reference_sha256: TextMap = field(metadata=_role(Role.BINARY))


@dataclass(frozen=True)
class ProgramCheckKey:
    """What a program's step-by-step check compares with, and on how many steps."""

    steps: int = field(metadata=_role(Role.WHAT))
    reference_sha256: TextMap = field(metadata=_role(Role.BINARY))


@dataclass(frozen=True)
class BinaryKey:
    """A tool binary run beside the cell (build/ompcost)."""

    binary_sha256: str = field(metadata=_role(Role.BINARY))


@dataclass(frozen=True)
class CountedKey:
    """The instruction lane: the counter and the binary it counted."""

    tool: str = field(metadata=_role(Role.WHAT))
    binary_sha256: str = field(metadata=_role(Role.BINARY))


@dataclass(frozen=True)
class CellKey:
    """Everything a cell's measurement depends on (the module's docstring: its projections)."""

    variant: str = field(metadata=_role(Role.WHAT))
    build: str = field(metadata=_role(Role.WHAT))
    input_sha256: str = field(metadata=_role(Role.WHAT))
    seed: int = field(metadata=_role(Role.WHAT))
    threads: int = field(metadata=_role(Role.WHAT))
    validate: bool = field(metadata=_role(Role.WHAT))
    exact: bool = field(metadata=_role(Role.WHAT))
    keep_output: bool = field(metadata=_role(Role.WHAT))
    binary_sha256: str = field(metadata=_role(Role.BINARY))
    baseline_sha256: str | None = field(metadata=_role(Role.BINARY))
    warmup: int = field(metadata=_role(Role.HOW))
    runs: int | str = field(metadata=_role(Role.HOW))
    timeout_s: float = field(metadata=_role(Role.HOW))
    ci: float | None = field(default=None, metadata=_optional(Role.HOW))
    max_runs: int | None = field(default=None, metadata=_optional(Role.HOW))
    max_time_s: float | None = field(default=None, metadata=_optional(Role.HOW))
    min_runs: int | None = field(default=None, metadata=_optional(Role.HOW))
    machine_id: str | None = field(default=None, metadata=_optional(Role.MACHINE))
    schedule: str | None = field(default=None, metadata=_optional(Role.WHAT))
    checks: ChecksKey | None = field(default=None, metadata=_optional(Role.WHAT))
    program_check: ProgramCheckKey | None = field(default=None, metadata=_optional(Role.WHAT))
    omp: TextMap | None = field(default=None, metadata=_optional(Role.WHAT))
    # MPI ranks: only a cell that runs as ranks has them (the others keep the ids they had)
    ranks: int | None = field(default=None, metadata=_optional(Role.WHAT))
    instructions: CountedKey | None = field(default=None, metadata=_optional(Role.COUNTED))
    openmp_costs: BinaryKey | None = field(default=None, metadata=_optional(Role.BESIDE))

    def to_json(self) -> dict[str, object]:
        """The key as stored in a record (and hashed into its id)."""
        return _project(self, "id")

    @classmethod
    def from_json(cls, raw: object) -> CellKey:
        """A stored key; KeyFormatError naming the field when it is not one."""
        return _parse(cls, raw, "key")

    @functools.cached_property
    def id(self) -> str:
        return content_id(self.to_json())

    @functools.cached_property
    def portable_id(self) -> str:
        return content_id(_project(self, "portable"))

    @functools.cached_property
    def group(self) -> str:
        return content_id(_project(self, "group"))

    @functools.cached_property
    def timed_group(self) -> str:
        return content_id(_project(self, "timed"))

    def group_fields(self) -> dict[str, object]:
        """The fields the group is hashed from, by name (what ran and how)."""
        return _project(self, "group")


def _project(obj: object, projection: str) -> dict[str, object]:
    keeps = _PROJECTIONS[projection]
    out: dict[str, object] = {}
    for f in fields(obj):  # type: ignore[arg-type]
        value = getattr(obj, f.name)
        flag = keeps.get(f.metadata["role"])
        if flag is None or (f.metadata["optional"] and value is None):
            continue
        out[f.name] = True if flag else _json_value(value, projection)
    return out


def _json_value(value: object, projection: str) -> object:
    if is_dataclass(value) and hasattr(value, "to_json"):  # a mapping of names
        return value.to_json()
    if is_dataclass(value):
        return _project(value, projection)
    if isinstance(value, tuple):
        return list(value)
    return value


def _parse(cls: type, raw: object, where: str) -> typing.Any:
    mapping = _mapping(raw, where)
    known = {f.name: f for f in fields(cls)}
    unknown = sorted(set(mapping) - set(known))
    if unknown:
        raise KeyFormatError(f"{where}: unknown field(s) {', '.join(unknown)}")
    hints = type_hints(cls)
    values: dict[str, object] = {}
    for name, f in known.items():
        if name not in mapping:
            if not f.metadata["optional"]:
                raise KeyFormatError(f"{where}.{name}: missing")
            continue
        values[name] = typed(mapping[name], hints[name], f"{where}.{name}")
    return cls(**values)


@functools.cache
def type_hints(cls: type) -> dict[str, typing.Any]:
    return typing.get_type_hints(cls)


def typed(value: object, hint: object, where: str,
          error: type[ValueError] = KeyFormatError) -> typing.Any:
    """`value` checked against the annotation `hint`, with nested keys parsed; `error` naming
    `where` when it is not one. JSON numbers keep their own type (an int stays an int where a
    float is allowed), as the id hashes them and as a record reads back."""
    for origin, option in _options(hint):
        if option is type(value) or (option is float and type(value) is int):
            return value
        if origin is tuple and isinstance(value, list):
            item = typing.get_args(option)[0]
            if all(type(v) is item for v in value):  # the common case, at once
                return tuple(value)
            return tuple(typed(v, item, f"{where}[{i}]", error) for i, v in enumerate(value))
        if origin is dict and isinstance(value, dict):
            return value
        if isinstance(option, type) and hasattr(option, "from_json"):
            return option.from_json(value, where)
        if isinstance(option, type) and is_dataclass(option):
            return _parse(option, value, where)
    raise error(f"{where}: {value!r} is not {getattr(hint, '__name__', None) or hint}")


@functools.cache
def _options(hint: object) -> tuple[tuple[object, object], ...]:
    """The types a value of `hint` may have, each with its generic origin (tuple, dict)."""
    options = typing.get_args(hint) if isinstance(hint, types.UnionType) else (hint,)
    return tuple((typing.get_origin(option), option) for option in options)


def _mapping(raw: object, where: str) -> Mapping[str, object]:
    if not isinstance(raw, Mapping):
        raise KeyFormatError(f"{where}: expected an object, got {raw!r}")
    return raw
