"""Render only what changed: one manifest beside the figures remembers each figure, keyed by
a hash of what it is drawn from (the function, its data frames, its arguments) and of the
plotting code, and each experiment's part (its section, warnings rows and headline facts),
keyed by a hash of its input files and of the report's code. A figure whose files are missing
or were altered since is drawn again; a part read back needs neither pandas nor matplotlib.

"The code" is every module of the harness a render can load, hashed by its bytes: the layers
the report stands on (the import-linter contracts keep the report and analysis from importing
what measures, plans, runs or builds) and the packages of the features whose parts it renders;
for the figures, those without the report's other modules.

Keys are of content, never of time, so the report is the same whether a figure was drawn or
reused. Standard library only (pandas is imported when a frame is hashed).
"""

import hashlib
import json
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any, NamedTuple

from harness.spec.facts import Variants
from harness.store.atomic import atomic_write_text
from harness.store.records import read_json, sha256_file

MANIFEST_NAME = ".manifest.json"
MANIFEST_VERSION = 3
PACKAGE_DIR = Path(__file__).resolve().parents[1]
# The code a render can load, as paths under the package (a folder: every module in it): the
# layers the report stands on; the figures need the same but the report's own other modules.
LAYERS_BELOW: tuple[str, ...] = ("analysis", "spec", "store", "stats", "errors.py", "repo.py",
                                 "__init__.py")
FIGURE_CODE: tuple[str, ...] = ("report/figures", "report/__init__.py", *LAYERS_BELOW)
REPORT_CODE: tuple[str, ...] = ("report", *LAYERS_BELOW)


def code_files(parts: Iterable[str]) -> list[Path]:
    """The modules of the parts (a folder: all of them, at any depth), sorted."""
    found: set[Path] = set()
    for part in parts:
        path = PACKAGE_DIR / part
        found.update(path.rglob("*.py") if path.is_dir() else [path] if path.is_file() else [])
    return sorted(found)


def code_version(files: Iterable[Path]) -> str:
    digest = hashlib.sha256()
    for path in files:
        digest.update(str(path.relative_to(PACKAGE_DIR)).encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def file_digest(path: Path) -> str:
    return sha256_file(path) if path.is_file() else "absent"


class CodeVersions(NamedTuple):
    """Hashes of the code that draws the figures and of the code that builds the parts."""

    plot: str
    report: str


def code_versions(features: Iterable[str] = ()) -> CodeVersions:
    """Reading every module is not free: a render computes this once for all its pages.
    `features`: the packages of the features it renders the parts of (ReportFeature.code)."""
    features = tuple(features)
    return CodeVersions(code_version(code_files((*FIGURE_CODE, *features))),
                        code_version(code_files((*REPORT_CODE, *features))))


def _digest_value(value: object, digest: Any) -> None:
    """Feed a figure argument into the hash: frames by their CSV text (exact float repr), the
    variants' facts by their canonical JSON."""
    if isinstance(value, Variants):
        digest.update(b"variants:")
        digest.update(value.digest().encode())
    elif hasattr(value, "to_csv") and hasattr(value, "columns"):
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
        data = read_json(self.path)  # no manifest, or a broken one: everything is rebuilt
        if not isinstance(data, dict) or data.get("version") != MANIFEST_VERSION:
            data = {}
        self.figures: dict[str, dict[str, Any]] = data.get("figures", {})
        self.parts: dict[str, dict[str, Any]] = data.get("parts", {})
        self.touched: list[str] = []  # stems drawn, kept or reused with a part, in order
        self._used_parts: set[str] = set()

    def _intact(self, entry: dict[str, Any]) -> bool:
        files = entry.get("files", {})
        return bool(files) and all(
            (self.fig_dir / name).is_file() and sha256_file(self.fig_dir / name) == sha
            for name, sha in files.items())

    def draw(self, function: Callable[..., Any], data: object, stem: Path,
             **kwargs: object) -> list[Path]:
        """`function(data, stem, **kwargs)` unless its files from the same inputs are on disk.
        Returns the figure's files (a one-file function's path in a list)."""
        digest = hashlib.sha256(
            f"{function.__module__}.{function.__qualname__}\0{self.code.plot}\0".encode())
        _digest_value(stem, digest)
        _digest_value(data, digest)
        for name in sorted(kwargs):
            digest.update(f"{name}=".encode())
            _digest_value(kwargs[name], digest)
        key = digest.hexdigest()
        self.touched.append(stem.name)
        entry = self.figures.get(stem.name)
        if entry is not None and entry.get("key") == key and self._intact(entry):
            return [self.fig_dir / name for name in entry["files"]]
        result = function(data, stem, **kwargs)
        paths = [result] if isinstance(result, Path) else list(result)
        self.figures[stem.name] = {"key": key,
                                   "files": {p.name: sha256_file(p) for p in paths}}
        return paths

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

    def save(self) -> None:
        """Keep only what this render used (removed figures and experiments drop out)."""
        used = set(self.touched)
        data = {
            "version": MANIFEST_VERSION,
            "figures": {k: v for k, v in sorted(self.figures.items()) if k in used},
            "parts": {k: v for k, v in sorted(self.parts.items()) if k in self._used_parts},
        }
        atomic_write_text(self.path, json.dumps(data, indent=1, sort_keys=True) + "\n")
