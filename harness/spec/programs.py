"""Programs: implementations of the model written elsewhere, benchmarked and checked beside
the variants (docs/programs.md). A command runs through `sh -c` in the config file's directory,
given an input that lists every particle. A program's cells are identified by its commands, the
content of every file they name and of its source, and its build: a rebuilt program is measured
again."""

import glob
import hashlib
import re
import shlex
import shutil
import string
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from harness.spec.facts import BASELINE, GRID

# The check run (docs/programs.md, "The check"): at most CHECK_MAX_STATES particle states,
# compared with seq's, past CHECK_SEQ_MAX_N particles with grid's; its `--replay` judges each step.
CHECK_MAX_STATES = 200_000
CHECK_SEQ_MAX_N = 1_999
FAST_REFERENCE = GRID
# The keys of a program cell's reference binaries (harness.plan.cellstore.program_references).
REFERENCE = "reference"
REPLAY = "replay"

INPUT = "input"
RANKS = "ranks"  # the MPI ranks of the cell: a program that names them runs as ranks
PLACEHOLDERS = (INPUT, "threads", RANKS)
PATH = "path"  # a class's programs (GLOB): the file the glob matched, quoted for the shell
DIR = "dir"  # a class's programs: the directory of the file matched (quoted in templates)
GLOB = "glob"
SOURCE = "source"
BUILD = "build"
PROGRAM_KEYS = ("command", "check", GLOB, SOURCE, BUILD)
# The placeholders a `build:` must use (the harness builds its own copies with them).
BUILD_REQUIRED = {"cc": "the compiler", "cflags": "the compiler's flags",
                  "out": "the binary to write"}
BUILD_PLACEHOLDERS = (*BUILD_REQUIRED, SOURCE)


def check_steps(n: int, steps: int) -> int:
    """The steps of a program's check run: all of them, or as many as CHECK_MAX_STATES
    particle states allow (the states after 0..S steps), at least one."""
    return steps if n == 0 else max(1, min(steps, CHECK_MAX_STATES // n - 1))


def reference_variant(n: int) -> str:
    """The variant a program's output is compared with, and whose `--replay` judges its steps."""
    return BASELINE if n <= CHECK_SEQ_MAX_N else FAST_REFERENCE


def template_problem(template: str, extra: tuple[str, ...] = (), build: bool = False
                     ) -> str | None:
    """What makes a command template (a `build:` one with `build`) unusable, or None: an
    unknown placeholder, a missing required one ({input}; a build's BUILD_REQUIRED) or stray
    braces. `extra`: names allowed beside the known ones ({path} in a class's template)."""
    known = (*(BUILD_PLACEHOLDERS if build else PLACEHOLDERS), *extra)
    try:
        parsed = list(string.Formatter().parse(template))
    except ValueError as exc:
        return f"unbalanced braces ({exc}; write {{{{ and }}}} for a literal brace)"
    for _, name, spec, conversion in parsed:
        if name is not None and (name not in known or spec or conversion):
            field = "{" + name + (f"!{conversion}" if conversion else "") + \
                (f":{spec}" if spec else "") + "}"
            return f"unknown placeholder {field} (known: " + ", ".join(
                "{" + p + "}" for p in known) + ")"
    names = {name for _, name, _, _ in parsed}
    if not build and INPUT not in names:
        return "no {input}: the program must be given the input file"
    return next((f"no {{{name}}} ({meaning})" for name, meaning in BUILD_REQUIRED.items()
                 if build and name not in names), None)


@dataclass(frozen=True)
class Program:
    """One program of a config: its timed command, its check command and where they run."""

    name: str
    command: str
    check: str
    directory: Path  # the config file's directory: the commands run there
    source: tuple[Path, ...] = ()  # its source files or directories (absolute)
    build: str = ""  # its build template ({cc}, {cflags}, {out}, {source}); "" without
    binary: str = ""  # a class's program: its {path} as the templates hold it

    @property
    def uses_ranks(self) -> bool:
        """Whether its command names {ranks}: it then runs as MPI ranks, one cell per count."""
        return any(field == RANKS for _, field, _, _ in string.Formatter().parse(self.command))

    def _in_directory(self, command: str) -> list[str]:
        """`sh -c 'cd DIR && COMMAND'`, so that hyperfine (which runs it without a shell of its
        own) and a rerun by hand both find the program's files."""
        return ["sh", "-c", f"cd {shlex.quote(str(self.directory))} && {command}"]

    def shell_command(self, template: str, input_file: Path, threads: int,
                      ranks: int = 1) -> list[str]:
        return self._in_directory(template.format(input=shlex.quote(str(input_file)),
                                                  threads=threads, ranks=ranks))

    def build_command(self, cc: str, cflags: str, out: Path) -> list[str]:
        """The argv that builds the program into `out` with the harness's compiler and flags."""
        sources = [str(p.relative_to(self.directory) if p.is_relative_to(self.directory) else p)
                   for p in self.source]
        return self._in_directory(self.build.format(
            cc=shlex.quote(cc), cflags=cflags, out=shlex.quote(str(out)),
            source=shlex.join(sources)))

    def with_binary(self, template: str, binary: Path) -> str | None:
        """The template with the program's binary replaced by another: a class's {path}, or
        the first word naming a file in its directory; None when it names none."""
        word = self.binary or next(
            (w for w in _words(template) if w and (self.directory / w).is_file()), "")
        if not word:
            return None
        replacement = shlex.quote(str(binary)).replace("{", "{{").replace("}", "}}")
        # The word as a whole shell word, where it is written unquoted.
        pattern = r"(?<![^\s;&|()<>])" + re.escape(word) + r"(?![^\s;&|()<>])"
        replaced, count = re.subn(pattern, lambda _: replacement, template, count=1)
        return replaced if count else None

    def source_files(self) -> list[Path]:
        found = {path for path in self.source if path.is_file()}
        for path in self.source:
            if path.is_dir():
                found.update(p for p in path.rglob("*") if p.is_file())
        return sorted(found)

    def named_files(self) -> list[Path]:
        """The files the commands name: each word that is a file relative to the directory,
        and the first word found on PATH (an interpreter)."""
        found = set()
        for template in (self.command, self.check):
            for k, word in enumerate(_words(template)):
                if word and (self.directory / word).is_file():
                    found.add((self.directory / word).resolve())
                elif k == 0 and word and "/" not in word and (located := shutil.which(word)):
                    found.add(Path(located).resolve())
        return sorted(found)

    def fingerprint(self) -> str:
        """sha256 of the commands and the content of every file they name: what the cells'
        ids and records hold where a variant's hold its binary's hash."""
        digest = hashlib.sha256()
        for part in (self.command, self.check):
            digest.update(part.encode() + b"\0")
        if self.build:  # without one, the hash of a program from before builds were known
            digest.update(b"build\0" + self.build.encode() + b"\0")
        for path in [*self.named_files(), *self.source_files()]:
            digest.update(str(path).encode() + b"\0")
            try:
                digest.update(hashlib.sha256(path.read_bytes()).digest())
            except OSError:
                digest.update(b"unreadable")
        return digest.hexdigest()


def _words(template: str) -> list[str]:
    """The shell words of a template with its placeholders blanked (their values vary)."""
    blank = template.replace("{{", "\0").replace("}}", "\1")
    for name in PLACEHOLDERS:
        blank = blank.replace("{" + name + "}", "")
    blank = blank.replace("\0", "{").replace("\1", "}")
    try:
        return shlex.split(blank, comments=True)
    except ValueError:
        return blank.split()


def from_mapping(name: str, value: Mapping[str, object], directory: Path,
                 path: Path | None = None) -> Program:
    """A Program from `command` and optional `check`, `source` and `build` (already checked).
    A class's program (`path`, the file its glob matched) has {path} and {dir} filled in:
    quoted in its templates, plain in `source:`."""
    def filled(template: object, quote: bool = True) -> str:
        text = str(template)
        for key, part in ((PATH, path), (DIR, None if path is None else path.parent)):
            if part is not None:
                shown = shlex.quote(str(part)).replace("{", "{{").replace("}", "}}")
                text = text.replace("{" + key + "}", shown if quote else str(part))
        return text

    raw = value.get(SOURCE)
    listed = [] if raw is None else [raw] if isinstance(raw, str) else list(raw)  # type: ignore[call-overload]
    return Program(name, filled(value["command"]), filled(value.get("check", value["command"])),
                   directory, tuple((directory / filled(s, False)).resolve() for s in listed),
                   filled(value.get(BUILD, "")), "" if path is None else filled("{" + PATH + "}"))


def class_members(pattern: str, directory: Path) -> list[tuple[str, Path]]:
    """The files a class's glob matches (relative to the config's directory, `**` allowed),
    each with its program name: the parts of its path that the glob's wildcards matched,
    joined by '-' (`submissions/*/sim` -> `alice`), other characters than letters, digits, '_',
    '.' and '-' as '_'."""
    wild = [k for k, part in enumerate(pattern.split("/")) if any(c in part for c in "*?[")]
    found = []
    for match in sorted(glob.glob(pattern, root_dir=directory, recursive=True)):
        parts = match.split("/")
        picked = [parts[k] for k in wild if k < len(parts)] or [parts[-1]]
        name = re.sub(r"[^A-Za-z0-9_.-]", "_", "-".join(picked)).lstrip("_.-") or "program"
        found.append((name, directory / match))
    return found
