"""Reading a config file: what each key accepts, with the checks every parser of a config uses
(each mistake a `HarnessError` naming the file, the key and what was expected), and its YAML
read strictly: a key named twice in one mapping is an error (PyYAML would keep the last one),
and the reading is bounded before a Python value is made (docs/hostile.md, "The harness")."""

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from harness.errors import HarnessError, config_error
from harness.spec.scenes import MAX_N, MAX_STEPS, MODES, read_text

MAX_SEED = 2**64 - 1
# The binaries' --threads bound (variants/core/sim_main.c).
MAX_THREADS = 4096


@dataclass(frozen=True)
class Kind:
    """What a key accepts: `parse` returns the normalised value or raises ValueError."""

    expected: str
    parse: Callable[[object], object]


def accepting(test: Callable[[object], bool]) -> Callable[[object], object]:
    def parse(value: object) -> object:
        if not test(value):
            raise ValueError
        return value

    return parse


def int_in(low: int, high: int | None = None) -> Callable[[object], object]:
    return accepting(lambda v: isinstance(v, int) and not isinstance(v, bool) and low <= v
                     and (high is None or v <= high))


def real_in(low: float = -math.inf, high: float = math.inf) -> Callable[[object], object]:
    """A finite number strictly between low and high, as a float."""
    def parse(value: object) -> object:
        if isinstance(value, bool) or not isinstance(value, str | int | float):
            raise ValueError
        result = float(value)  # YAML 1.1 reads 1e7 as a string
        if not (math.isfinite(result) and low < result < high):
            raise ValueError
        return result

    return parse


real = real_in()


def one_of(options: Sequence[str]) -> Kind:
    return Kind("one of " + ", ".join(options), accepting(lambda v: v in options))


def optional(kind: Kind) -> Kind:
    """`kind`, or null for None."""
    return Kind(kind.expected, lambda v: None if v is None else kind.parse(v))


def many(kind: Kind) -> Kind:
    """A value or a non-empty list of values of `kind`, as a tuple."""
    def parse(value: object) -> object:
        values = value if isinstance(value, list) else [value]
        if not values:
            raise ValueError
        return tuple(kind.parse(v) for v in values)

    return Kind(f"{kind.expected} or a non-empty list of them", parse)


POSITIVE_INT = Kind("a positive integer", int_in(1))
NON_NEGATIVE_INT = Kind("a non-negative integer", int_in(0))
SEED = Kind(f"an integer in [0, {MAX_SEED}]", int_in(0, MAX_SEED))
POSITIVE_REAL = Kind("a positive finite number", real_in(0.0))
REAL = Kind("a finite number", real)
STRING = Kind("a non-empty string", accepting(lambda v: isinstance(v, str) and bool(v)))
BOOLEAN = Kind("true or false", accepting(lambda v: isinstance(v, bool)))

# The bounds of what the binaries accept (harness.spec.scenes, MAX_THREADS).
THREADS = Kind(f"a positive integer (at most {MAX_THREADS})", int_in(1, MAX_THREADS))
MAX_RANKS = 65536
RANKS = Kind(f"a positive integer (at most {MAX_RANKS})", int_in(1, MAX_RANKS))
RANDOM_KINDS: dict[str, Kind] = {
    "n": Kind(f"a positive integer (at most {MAX_N})", int_in(1, MAX_N)),
    "L": POSITIVE_REAL,
    "r": POSITIVE_REAL,
    "steps": Kind(f"a non-negative integer (at most {MAX_STEPS})", int_in(0, MAX_STEPS)),
    "mode": one_of(MODES),
    "seed": SEED,
}


# A generator's own keys, by the type of their defaults (bool first: a bool is an int too).
DEFAULT_KINDS = ((bool, BOOLEAN), (int, Kind("a 64-bit integer", int_in(-(2**63), 2**63 - 1))),
                 (float, REAL))


def generator_kind(name: str, default: object) -> Kind:
    return RANDOM_KINDS.get(name) or next(
        (kind for type_, kind in DEFAULT_KINDS if isinstance(default, type_)), STRING)


def reject_unknown(raw: Mapping[str, object], allowed: Sequence[str], prefix: str,
                    source: Path) -> None:
    for key in raw:
        if key not in allowed:
            raise config_error(source, f"{prefix}{key}", "one of " + ", ".join(allowed),
                               "an unknown key")


def check(value: object, label: str, kind: Kind, source: Path) -> object:
    try:
        return kind.parse(value)
    except (ValueError, TypeError):
        raise config_error(source, label, kind.expected, value) from None


def settings(value: object, table: Mapping[str, Kind], label: str,
             source: Path) -> dict[str, Any]:
    """A mapping of the keys of `table`, each checked by its kind: the keys given, as the
    keyword arguments of the dataclass they set (an absent key keeps its default)."""
    raw = mapping(value, label, source)
    reject_unknown(raw, tuple(table), f"{label}.", source)
    return {key: check(raw[key], f"{label}.{key}", kind, source)
            for key, kind in table.items() if key in raw}


def name_list(value: object, label: str, known: Sequence[str], source: Path,
              allow_empty: bool = False) -> tuple[str, ...]:
    """A name or a list of distinct names among `known` (at least one unless `allow_empty`)."""
    expected = ("a list of " if allow_empty else "a non-empty list of ") + ", ".join(known)
    items = [value] if isinstance(value, str) else value
    if not isinstance(items, list) or not (items or allow_empty):
        raise config_error(source, label, expected, value)
    for item in items:
        if item not in known:
            raise config_error(source, label, "names among " + ", ".join(known), item)
    if len(set(items)) != len(items):
        raise config_error(source, label, "names without repeats", value)
    return tuple(items)


def file_beside(path: str, source: Path, label: str, what: str) -> Path:
    """`path` relative to the config's directory, resolved; a config error expecting `what`
    where it is no file."""
    resolved = (source.resolve().parent / path).resolve()
    if not resolved.is_file():
        raise config_error(source, label, f"{what} relative to the config", path)
    return resolved


def mapping(value: object, label: str, source: Path) -> Mapping[str, object]:
    if not isinstance(value, dict):
        raise config_error(source, label, "a mapping", value)
    return value


# --- YAML read strictly ---

# Far beyond any real config, far below what would take memory or time to read.
MAX_YAML_BYTES = 4 * 1024 * 1024
MAX_YAML_DEPTH = 64
MAX_YAML_VALUES = 100_000  # scalars and collections, every alias expanded
MAX_INT_CHARS = 40  # an integer's text: 2**64 has 20 digits


class DuplicateKeyError(yaml.YAMLError):
    def __init__(self, key: object, first_line: int, line: int) -> None:
        super().__init__(f"key '{key}' appears twice: on line {first_line} and on line {line}")


class StrictLoader(yaml.SafeLoader):
    """yaml.SafeLoader that refuses a duplicate key in any mapping, and an integer too long to
    be a count (Python refuses to convert one past 4300 digits)."""

    def construct_mapping(self, node: yaml.MappingNode,  # type: ignore[override]
                          deep: bool = False) -> dict[object, object]:
        seen: dict[object, int] = {}
        for key_node, _ in node.value:
            if key_node.tag == "tag:yaml.org,2002:merge":
                continue
            key = self.construct_object(key_node, deep=True)  # type: ignore[no-untyped-call]
            line = key_node.start_mark.line + 1
            try:
                if key in seen:
                    raise DuplicateKeyError(key, seen[key], line)
                seen[key] = line
            except TypeError:  # an unhashable key: SafeLoader's own error follows
                continue
        return super().construct_mapping(node, deep=deep)

    def construct_yaml_int(self, node: yaml.ScalarNode) -> int:
        if len(str(node.value)) > MAX_INT_CHARS:
            raise yaml.constructor.ConstructorError(
                None, None, f"an integer of {len(str(node.value))} characters (at most "
                f"{MAX_INT_CHARS})", node.start_mark)
        return super().construct_yaml_int(node)  # type: ignore[no-untyped-call,no-any-return]


StrictLoader.add_constructor("tag:yaml.org,2002:int", StrictLoader.construct_yaml_int)


# The shape is read with libyaml's parser where PyYAML has it: PyYAML's own scanner takes about a
# second to open a thousand nested flow collections, libyaml a millisecond.
SHAPE_LOADER = getattr(yaml, "CSafeLoader", StrictLoader)


def load_yaml(text: str) -> object:
    """The YAML's value; a YAMLError where it nests too deep or expands to too many values
    (each alias counted as the values of its anchor), found before any value is made."""
    anchored: dict[str, int] = {}  # anchor -> the values it stands for
    open_at: list[tuple[int, str | None]] = []  # each open collection: values before it, anchor
    values = 0
    for event in yaml.parse(text, Loader=SHAPE_LOADER):
        line = event.start_mark.line + 1 if event.start_mark else 0
        if isinstance(event, yaml.AliasEvent):
            values += anchored.get(str(event.anchor), 1)
        elif isinstance(event, yaml.ScalarEvent):
            values += 1
            if event.anchor is not None:
                anchored[event.anchor] = 1
        elif isinstance(event, yaml.CollectionStartEvent):
            open_at.append((values, event.anchor))
            values += 1
            if len(open_at) > MAX_YAML_DEPTH:
                raise yaml.YAMLError(f"nested deeper than {MAX_YAML_DEPTH} levels (line {line})")
        elif isinstance(event, yaml.CollectionEndEvent):
            before, anchor = open_at.pop()
            if anchor is not None:
                anchored[anchor] = values - before
        if values > MAX_YAML_VALUES:
            raise yaml.YAMLError(f"more than {MAX_YAML_VALUES} values, each alias counted where "
                                 f"it is used (line {line})")
    return yaml.load(text, Loader=StrictLoader)


# How much of PyYAML's message (it quotes the offending line) an error line keeps.
MAX_DETAIL_CHARS = 300


def read_mapping(source: Path) -> dict[str, object]:
    """The top-level mapping of a YAML config file; a HarnessError naming the file otherwise."""
    text = read_text(source, "config file", MAX_YAML_BYTES)
    try:
        raw = load_yaml(text)
    except DuplicateKeyError as exc:
        raise HarnessError(f"{source}: {exc}") from None
    except yaml.YAMLError as exc:
        detail = " ".join(str(exc).split())
        if len(detail) > MAX_DETAIL_CHARS:
            detail = detail[:MAX_DETAIL_CHARS - 3] + "..."
        raise HarnessError(f"{source}: invalid YAML: {detail}") from None
    if not isinstance(raw, dict):
        raise HarnessError(f"{source}: expected a mapping of config keys, got {type(raw).__name__}")
    return raw
