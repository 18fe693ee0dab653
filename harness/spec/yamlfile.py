"""YAML read strictly: a key named twice in one mapping is an error (PyYAML would keep the last
one without a word), and a file that cannot be read or parsed is one error line.

Nothing in a file can make the reading unbounded: the file's size, its nesting depth, the
values it expands to (an alias counts each time it is used, so a small "billion laughs" file
is refused before anything is built) and the digits of an integer are limited, and checked on
the parser's events, which need no recursion, before a Python value is made."""

from __future__ import annotations

from pathlib import Path

import yaml

from harness.errors import HarnessError

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


class ShapeError(yaml.YAMLError):
    """A document nested too deep or expanding to too many values."""


def check_shape(text: str) -> None:
    """Raise ShapeError where the YAML nests too deep or expands to too many values (each alias
    counted as the values of its anchor)."""
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
                raise ShapeError(f"nested deeper than {MAX_YAML_DEPTH} levels (line {line})")
        elif isinstance(event, yaml.CollectionEndEvent):
            before, anchor = open_at.pop()
            if anchor is not None:
                anchored[anchor] = values - before
        if values > MAX_YAML_VALUES:
            raise ShapeError(f"more than {MAX_YAML_VALUES} values, each alias counted where it "
                             f"is used (line {line})")


def load_yaml(text: str) -> object:
    check_shape(text)
    return yaml.load(text, Loader=StrictLoader)


def read_text(source: Path, what: str, max_bytes: int | None = None) -> str:
    """A file's UTF-8 text; a HarnessError naming the file (`what` says what it is) when it is
    missing, unreadable, larger than max_bytes or not UTF-8."""
    try:
        if max_bytes is not None and source.stat().st_size > max_bytes:
            raise HarnessError(f"{source}: {what} of {source.stat().st_size} bytes is larger "
                               f"than {max_bytes}")
        data = source.read_bytes()
    except FileNotFoundError:
        raise HarnessError(f"{source}: no such {what}") from None
    except OSError as exc:
        raise HarnessError(f"{source}: cannot read {what}: {exc.strerror}") from None
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise HarnessError(f"{source}: {what} is not UTF-8 text: byte 0x{data[exc.start]:02x} "
                           f"on line {line} (offset {exc.start})") from None


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
