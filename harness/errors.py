"""The one error type the harness reports to the user (exit status 2, no traceback)."""

from __future__ import annotations

from pathlib import Path


class HarnessError(Exception):
    """A user-facing error: bad config, missing tool, failed build. Printed as `error: ...`."""


def config_error(path: Path | str, key: str, expected: str, got: object) -> HarnessError:
    """An error naming the config file, the offending key, what was expected and what was got."""
    return HarnessError(f"{path}: key '{key}': expected {expected}, got {describe_value(got)}")


def describe_value(value: object) -> str:
    """A short, one-line rendering of a YAML value for an error message."""
    if isinstance(value, _Missing):
        return "nothing (the key is missing)"
    text = repr(value)
    return text if len(text) <= MAX_VALUE_CHARS else text[: MAX_VALUE_CHARS - 3] + "..."


MAX_VALUE_CHARS = 80


class _Missing:
    """Marks a required key that is absent."""

    def __repr__(self) -> str:
        return "<missing>"


MISSING = _Missing()
