"""The one error type the harness reports to the user (exit status 2, no traceback)."""

import errno
import reprlib
from pathlib import Path


class HarnessError(Exception):
    """A user-facing error: bad config, missing tool, failed build. Printed as `error: ...`."""


class StorageError(HarnessError):
    """The harness cannot keep what it measures (the place it writes to is full, read-only, not
    its to write): a fault of the machine or the place, never a cell's result; the run stops."""


# The OS errors a user causes by where the harness is pointed or what it is left: each ends a
# command with one `error:` line (exit 2), never a traceback.
USER_ERRNOS: frozenset[int] = frozenset({
    errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EROFS, errno.EACCES, errno.EPERM,
    errno.ENOTDIR, errno.EISDIR, errno.EEXIST, errno.ENAMETOOLONG, errno.ELOOP})


def os_error_text(exc: OSError) -> str:
    """An OS error as `PATH: why` (the path it names, where it names one)."""
    why = exc.strerror or str(exc)
    return f"{exc.filename}: {why}" if exc.filename is not None else why


def storage_error(path: Path | str, exc: OSError, doing: str = "write") -> StorageError:
    """`PATH: cannot DOING: why`, for an OS error met while keeping results at `path`."""
    return StorageError(f"{path}: cannot {doing}: {exc.strerror or exc}")


def config_error(path: Path | str, key: str, expected: str, got: object) -> HarnessError:
    """An error naming the config file, the offending key (as it is when short and printable,
    else previewed), what was expected and what was got."""
    shown = key if len(key) <= MAX_VALUE_CHARS and key.isprintable() else describe_value(key)
    return HarnessError(f"{path}: key '{shown}': expected {expected}, got {describe_value(got)}")


MAX_VALUE_CHARS = 80


class _Preview(reprlib.Repr):
    """repr() that looks at a bounded part of a value: a few levels, a few items of each
    collection, the ends of a long string, so a value that is huge or shares itself many times
    (a YAML alias bomb) is previewed at once."""

    def __init__(self) -> None:
        super().__init__()
        self.maxlevel = 3
        self.maxlist = self.maxtuple = self.maxdict = self.maxset = 4
        self.maxstring = self.maxother = self.maxlong = MAX_VALUE_CHARS

    def repr_int(self, x: int, level: int) -> str:
        # repr() of an int past Python's 4300 digits raises; its size is what matters.
        if x.bit_length() > 4 * MAX_VALUE_CHARS:
            return f"an integer of about {int(x.bit_length() * 0.30103)} digits"
        return super().repr_int(x, level)


_PREVIEW = _Preview()


def describe_value(value: object) -> str:
    """A short, one-line rendering of a YAML value for an error message."""
    if isinstance(value, _Missing):
        return "nothing (the key is missing)"
    text = _PREVIEW.repr(value)
    return text if len(text) <= MAX_VALUE_CHARS else text[: MAX_VALUE_CHARS - 3] + "..."


class _Missing:
    """Marks a required key that is absent."""

    def __repr__(self) -> str:
        return "<missing>"


MISSING = _Missing()
