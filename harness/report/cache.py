"""Render only what changed: figures keyed by a hash of their data, experiment parts keyed
by a hash of their input files, both remembered in one manifest beside the figures.

- A figure is re-drawn only when the hash of what it is drawn from (the function, its data
  frames, its arguments) or the plotting code changed, or when its files are missing or were
  altered since. Otherwise the files on disk are reused as they are.
- An experiment's part of the report (its section, its warnings rows, its headline facts) is
  rebuilt only when one of its input files or the report's code changed; a hit needs neither
  pandas nor matplotlib.

Both are keyed by content, never by time, so the rendered report is the same whether a figure
was drawn or reused. Standard library only (pandas is imported when a frame is hashed;
harness.results needs no packages).
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

from harness.results import sha256_file

MANIFEST_NAME = ".manifest.json"
MANIFEST_VERSION = 1
HARNESS_DIR = Path(__file__).resolve().parents[1]
# The code a figure's pixels depend on; any other change keeps the figures.
PLOT_CODE: tuple[Path, ...] = (HARNESS_DIR / "plots.py", HARNESS_DIR / "tables.py",
                               HARNESS_DIR / "stats.py", HARNESS_DIR / "strategy_study.py",
                               HARNESS_DIR / "phases.py")
# The code an experiment's part depends on: all of the report, and what it calls.
REPORT_CODE: tuple[Path, ...] = (*PLOT_CODE, *sorted((HARNESS_DIR / "report").glob("*.py")))


def code_version(files: Iterable[Path]) -> str:
    digest = hashlib.sha256()
    for path in files:
        digest.update(path.name.encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def _digest_value(value: object, digest: Any) -> None:
    """Feed a figure argument into the hash: frames by their CSV text (exact float repr)."""
    if hasattr(value, "to_csv") and hasattr(value, "columns"):
        digest.update(b"frame:")
        digest.update(value.to_csv(index=True).encode())  # type: ignore[attr-defined]
    elif isinstance(value, Path):
        digest.update(f"path:{value.name}".encode())  # where it is written is the stem's job
    else:
        digest.update(repr(value).encode())
    digest.update(b"\0")


class Manifest:
    """report/figures/.manifest.json: what each figure and each experiment part was made from."""

    def __init__(self, fig_dir: Path) -> None:
        self.fig_dir = fig_dir
        self.path = fig_dir / MANIFEST_NAME
        self.plot_code = code_version(PLOT_CODE)
        self.report_code = code_version(REPORT_CODE)
        data = self._read()
        self.figures: dict[str, dict[str, Any]] = data.get("figures", {})
        self.parts: dict[str, dict[str, Any]] = data.get("parts", {})
        self.drawn: list[str] = []  # stems drawn by this render, in order
        self.reused: list[str] = []  # stems whose files were kept
        self.touched: list[str] = []  # stems drawn or kept, in order
        self._used_figures: set[str] = set()
        self._used_parts: set[str] = set()

    def _read(self) -> dict[str, Any]:
        try:
            data = json.loads(self.path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return {}  # no manifest, or a broken one: everything is rebuilt
        if not isinstance(data, dict) or data.get("version") != MANIFEST_VERSION:
            return {}
        return data

    # --- figures ---------------------------------------------------------------------------

    def figure_key(self, function: Callable[..., object], args: tuple, kwargs: dict) -> str:
        digest = hashlib.sha256()
        digest.update(f"{function.__module__}.{function.__qualname__}\0{self.plot_code}\0".encode())
        for value in args:
            _digest_value(value, digest)
        for name in sorted(kwargs):
            digest.update(f"{name}=".encode())
            _digest_value(kwargs[name], digest)
        return digest.hexdigest()

    def _intact(self, entry: dict[str, Any]) -> bool:
        files = entry.get("files", {})
        return bool(files) and all(
            (self.fig_dir / name).is_file() and sha256_file(self.fig_dir / name) == sha
            for name, sha in files.items())

    def draw(self, function: Callable[..., Any], data: object, stem: Path, *more: object,
             **kwargs: object) -> list[Path]:
        """`function(data, stem, *more, **kwargs)` unless its files from the same inputs are
        on disk. Returns the figure's files (a one-file function's path in a list)."""
        args = (data, *more)
        key = self.figure_key(function, (stem, *args), kwargs)
        self._used_figures.add(stem.name)
        self.touched.append(stem.name)
        entry = self.figures.get(stem.name)
        if entry is not None and entry.get("key") == key and self._intact(entry):
            self.reused.append(stem.name)
            return [self.fig_dir / name for name in entry["files"]]
        result = function(data, stem, *more, **kwargs)
        paths = [result] if isinstance(result, Path) else list(result)
        self.figures[stem.name] = {"key": key,
                                   "files": {p.name: sha256_file(p) for p in paths}}
        self.drawn.append(stem.name)
        return paths

    # --- experiment parts ------------------------------------------------------------------

    def part_key(self, input_digest: str) -> str:
        return hashlib.sha256(f"{input_digest}\0{self.report_code}".encode()).hexdigest()

    def get_part(self, name: str, key: str) -> dict[str, Any] | None:
        """A stored part made from the same inputs whose figures are all intact, or None."""
        self._used_parts.add(name)
        entry = self.parts.get(name)
        if entry is None or entry.get("key") != key:
            return None
        figures = entry.get("figures", [])
        if not all(f in self.figures and self._intact(self.figures[f]) for f in figures):
            return None
        self._used_figures.update(figures)
        self.reused.extend(figures)
        return entry["part"]

    def put_part(self, name: str, key: str, part: dict[str, Any], figures: list[str]) -> None:
        self._used_parts.add(name)
        self.parts[name] = {"key": key, "part": part, "figures": sorted(figures)}

    # --- writing ---------------------------------------------------------------------------

    def save(self) -> None:
        """Keep only what this render used (removed figures and experiments drop out)."""
        data = {
            "version": MANIFEST_VERSION,
            "figures": {k: v for k, v in sorted(self.figures.items()) if k in self._used_figures},
            "parts": {k: v for k, v in sorted(self.parts.items()) if k in self._used_parts},
        }
        write_text_atomic(self.path, json.dumps(data, indent=1, sort_keys=True) + "\n")


FILE_MODE = 0o644  # the report is for reading; mkstemp makes files private


def write_text_atomic(path: Path, text: str) -> None:
    """Write through a temporary sibling and rename it into place: a reader (a browser, a
    concurrent render) never sees a half-written file."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as handle:
            handle.write(text)
        os.chmod(tmp, FILE_MODE)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
