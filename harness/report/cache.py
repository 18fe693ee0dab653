"""Render only what changed: figures keyed by a hash of their data, experiment parts keyed
by a hash of their input files, both remembered in one manifest beside the figures.

- A figure is re-drawn only when the hash of what it is drawn from (the function, its data
  frames, its arguments) or the plotting code changed, or when its files are missing or were
  altered since. Otherwise the files on disk are reused as they are.
- An experiment's part of the report (its section, its warnings rows, its headline facts) is
  rebuilt only when one of its input files or the report's code changed; a hit needs neither
  pandas nor matplotlib.

"The code" is found, not listed: every module of the harness that the figures (or the whole
report) import, directly or through others, read from their import statements (code_closure).
A figure's key also holds the facts of the variants its results were measured with
(harness.spec.facts.current), which decide the order and colours of what is drawn.

Both are keyed by content, never by time, so the rendered report is the same whether a figure
was drawn or reused. Standard library only (pandas is imported when a frame is hashed).
"""

from __future__ import annotations

import ast
import hashlib
import json
from collections.abc import Callable, Iterable
from importlib.util import resolve_name
from pathlib import Path
from typing import Any, NamedTuple

from harness.spec.facts import current
from harness.store.atomic import atomic_write_text
from harness.store.records import sha256_file

MANIFEST_NAME = ".manifest.json"
MANIFEST_VERSION = 2
PACKAGE = "harness"
PACKAGE_DIR = Path(__file__).resolve().parents[1]
# The modules whose code a figure's pixels depend on (with all they import); any other change
# keeps the figures.
FIGURE_MODULES: tuple[str, ...] = ("harness.report.figures",)
# The modules an experiment's part depends on: the report's, and all they import.
REPORT_MODULES: tuple[str, ...] = ("harness.report",)


def module_files(name: str, whole: bool = False) -> list[Path]:
    """The file of a harness module: a package's __init__.py (what importing it loads), or
    with `whole` every module under the package."""
    base = PACKAGE_DIR.joinpath(*name.split(".")[1:])
    if base.is_dir():
        init = [base / "__init__.py"] if (base / "__init__.py").is_file() else []
        return sorted(base.rglob("*.py")) if whole else init
    path = base.with_suffix(".py")
    return [path] if path.is_file() else []


def _module_name(path: Path) -> str:
    relative = path.relative_to(PACKAGE_DIR).with_suffix("")
    parts = [PACKAGE, *relative.parts]
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imported(path: Path) -> set[str]:
    """The harness modules a file imports (absolute or relative; `from a import b` names both
    a and a.b, since b may be a module)."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    package = _module_name(path) if path.name == "__init__.py" else \
        _module_name(path).rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = resolve_name("." * node.level + (node.module or ""), package)
            found.add(base)
            found.update(f"{base}.{alias.name}" for alias in node.names)
    return {name for name in found if name == PACKAGE or name.startswith(PACKAGE + ".")}


def code_closure(modules: Iterable[str]) -> list[Path]:
    """Every file of the harness the modules (packages: all their modules) are made of or
    import, directly or not; a module's packages count too (they are loaded before it)."""
    todo = [f for name in modules for f in module_files(name, whole=True)]
    seen: set[Path] = set()
    while todo:
        path = todo.pop()
        if path in seen:
            continue
        seen.add(path)
        names = imported(path)
        module = _module_name(path)
        names.update(module.rsplit(".", k)[0] for k in range(1, module.count(".") + 1))
        for name in names:
            todo += [f for f in module_files(name) if f not in seen]
    return sorted(seen)


def code_version(files: Iterable[Path]) -> str:
    digest = hashlib.sha256()
    for path in files:
        digest.update(str(path.relative_to(PACKAGE_DIR)).encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


class CodeVersions(NamedTuple):
    """Hashes of the code that draws the figures and of the code that builds the parts."""

    plot: str
    report: str


def code_versions() -> CodeVersions:
    """Reading every module is not free: a render computes this once for all its pages."""
    return CodeVersions(code_version(code_closure(FIGURE_MODULES)),
                        code_version(code_closure(REPORT_MODULES)))


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

    def __init__(self, fig_dir: Path, code: CodeVersions) -> None:
        self.fig_dir = fig_dir
        self.path = fig_dir / MANIFEST_NAME
        self.code = code
        data = self._read()
        self.figures: dict[str, dict[str, Any]] = data.get("figures", {})
        self.parts: dict[str, dict[str, Any]] = data.get("parts", {})
        self.touched: list[str] = []  # stems drawn, kept or reused with a part, in order
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
        digest.update(f"{function.__module__}.{function.__qualname__}\0{self.code.plot}\0".encode())
        digest.update(f"{current().digest()}\0".encode())
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

    def draw(self, function: Callable[..., Any], data: object, stem: Path,
             **kwargs: object) -> list[Path]:
        """`function(data, stem, **kwargs)` unless its files from the same inputs are on disk.
        Returns the figure's files (a one-file function's path in a list)."""
        key = self.figure_key(function, (stem, data), kwargs)
        self.touched.append(stem.name)
        entry = self.figures.get(stem.name)
        if entry is not None and entry.get("key") == key and self._intact(entry):
            return [self.fig_dir / name for name in entry["files"]]
        result = function(data, stem, **kwargs)
        paths = [result] if isinstance(result, Path) else list(result)
        self.figures[stem.name] = {"key": key,
                                   "files": {p.name: sha256_file(p) for p in paths}}
        return paths

    # --- experiment parts ------------------------------------------------------------------

    def part(self, name: str, input_digest: str, build: Callable[[], dict[str, Any]],
             valid: Callable[[dict[str, Any]], bool] | None = None) -> dict[str, Any]:
        """The part stored under `name` when it was made from the same inputs and code, its
        figures are all intact and `valid` (if given) accepts it, else `build()` stored with
        the figures it drew."""
        self._used_parts.add(name)
        key = hashlib.sha256(f"{input_digest}\0{self.code.report}".encode()).hexdigest()
        entry = self.parts.get(name)
        if entry is not None and entry.get("key") == key \
                and (valid is None or valid(entry["part"])):
            figures = entry.get("figures", [])
            if all(f in self.figures and self._intact(self.figures[f]) for f in figures):
                self.touched += figures
                return entry["part"]
        first = len(self.touched)
        part = build()
        self.parts[name] = {"key": key, "part": part, "figures": sorted(self.touched[first:])}
        return part

    # --- writing ---------------------------------------------------------------------------

    def save(self) -> None:
        """Keep only what this render used (removed figures and experiments drop out)."""
        used = set(self.touched)
        data = {
            "version": MANIFEST_VERSION,
            "figures": {k: v for k, v in sorted(self.figures.items()) if k in used},
            "parts": {k: v for k, v in sorted(self.parts.items()) if k in self._used_parts},
        }
        atomic_write_text(self.path, json.dumps(data, indent=1, sort_keys=True) + "\n")
