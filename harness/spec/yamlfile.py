"""YAML read strictly: a key named twice in one mapping is an error (PyYAML would keep the last
one without a word), and a file that cannot be read or parsed is one error line."""

from __future__ import annotations

from pathlib import Path

import yaml

from harness.errors import HarnessError


class DuplicateKeyError(yaml.YAMLError):
    """A mapping that names one key twice (PyYAML keeps the last one without a word)."""

    def __init__(self, key: object, first_line: int, line: int) -> None:
        super().__init__(f"key '{key}' appears twice: on line {first_line} and on line {line}")


class StrictLoader(yaml.SafeLoader):
    """yaml.SafeLoader that refuses a duplicate key in any mapping, at any depth."""

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


def load_yaml(text: str) -> object:
    """YAML text to Python values; a duplicate key is a DuplicateKeyError."""
    return yaml.load(text, Loader=StrictLoader)



def read_mapping(source: Path) -> dict[str, object]:
    """The top-level mapping of a YAML file; a HarnessError naming the file otherwise."""
    try:
        text = source.read_text()
    except FileNotFoundError:
        raise HarnessError(f"{source}: no such config file") from None
    except OSError as exc:
        raise HarnessError(f"{source}: cannot read: {exc.strerror}") from None
    try:
        raw = load_yaml(text)
    except DuplicateKeyError as exc:
        raise HarnessError(f"{source}: {exc}") from None
    except yaml.YAMLError as exc:
        detail = " ".join(str(exc).split())
        raise HarnessError(f"{source}: invalid YAML: {detail}") from None
    if not isinstance(raw, dict):
        raise HarnessError(f"{source}: expected a mapping of config keys, got {type(raw).__name__}")
    return raw
