"""What a config runs: its variants and builds, and its own binaries and programs (command
templates, built from a source, or a class of them matched by a glob)."""

from __future__ import annotations

from collections.abc import Collection, Mapping, Sequence
from pathlib import Path

from harness.errors import MISSING, HarnessError, config_error
from harness.spec import kinds, programs
from harness.spec.builds import BUILDS, DEFAULT_BUILD
from harness.spec.config import NAME_RULE, is_valid_name
from harness.spec.facts import MPI_INSTALL


def parse_variants(raw: Mapping[str, object], source: Path, known_variants: Sequence[str],
                   unbuilt: Collection[str] = ()
                   ) -> tuple[tuple[str, ...], tuple[str, ...], tuple[tuple[str, Path], ...],
                              tuple[programs.Program, ...]]:
    """The config's variants and builds, its binaries and its programs: a custom binary or a
    program is a new variant name, listed under `variants` (a class: every program its glob
    matched), and built f64 only."""
    binaries = parse_binaries(raw.get("binaries", {}), source, known_variants)
    taken = (*known_variants, *(b[0] for b in binaries))
    programs_, classes = parse_programs(raw.get("programs", {}), source, taken)
    known = (*taken, *(p.name for p in programs_), *classes)
    asked = raw.get("variants")
    for name in asked if isinstance(asked, list) else ():
        if name in unbuilt and name not in known:
            raise HarnessError(f"{source}: key 'variants': {name!r} is an MPI variant, which "
                               "make leaves out where mpicc is not found; install Open MPI: "
                               f"{MPI_INSTALL}")
    listed = kinds.name_list(raw.get("variants", MISSING), "variants", known, source)
    # A class in `variants` stands for every program its glob matched.
    variants = tuple(dict.fromkeys(m for v in listed for m in classes.get(v, (v,))))
    builds = kinds.name_list(raw.get("builds", [DEFAULT_BUILD]), "builds", BUILDS, source)
    for variant, _ in binaries:
        if variant in variants and builds != (DEFAULT_BUILD,):
            raise config_error(source, f"binaries.{variant}", "builds: [f64] with a custom "
                               "binary", list(builds))
    for program in programs_:
        if program.name not in variants:
            raise config_error(source, f"programs.{program.name}", "a program also listed "
                               "under variants", "not listed")
        if builds != (DEFAULT_BUILD,):
            raise config_error(source, f"programs.{program.name}", "builds: [f64] with a "
                               "program", list(builds))
    return variants, builds, binaries, programs_


def _check_new_name(name: object, label: str, taken: Sequence[str], source: Path) -> None:
    """A name for a custom binary or a program: a valid name no variant has."""
    if name in taken or not is_valid_name(name):
        raise config_error(source, label, f"a new variant name ({NAME_RULE}; not one of "
                           + ", ".join(taken) + ")", name)


def _check_source(value: object, where: str, config: Path, extra: tuple[str, ...]) -> None:
    """`source:`: a path or a non-empty list of paths relative to the config, each existing
    (a class's, with {path} or {dir}, is checked per program when it is built)."""
    listed = [value] if isinstance(value, str) else value
    expected = "a source file or directory relative to the config, or a list of them"
    if not isinstance(listed, list) or not listed or not all(
            isinstance(p, str) and p.strip() for p in listed):
        raise config_error(config, where, expected, value)
    if extra:
        return
    for path in listed:
        if not (config.resolve().parent / path).exists():
            raise config_error(config, where, f"{expected} (not found: "
                               f"{config.resolve().parent / path})", value)


def parse_binaries(value: object, source: Path,
                    variants: Sequence[str]) -> tuple[tuple[str, Path], ...]:
    raw = kinds.mapping(value, "binaries", source)
    result = []
    for name, path in raw.items():
        label = f"binaries.{name}"
        _check_new_name(name, label, variants, source)
        if not isinstance(path, str) or not path:
            raise config_error(source, label, "a path to an executable", path)
        resolved = (source.resolve().parent / path).resolve()
        if not resolved.is_file():
            raise config_error(source, label, "an executable file relative to the config", path)
        result.append((name, resolved))
    return tuple(result)


PROGRAM_FORMS = ('a command template such as "./sim {threads} < {input}", or '
                 '{command: TEMPLATE, check: TEMPLATE, source: PATH, build: TEMPLATE}, or a '
                 'class: {glob: PATTERN, command: TEMPLATE with {path}}')
BUILD_FORM = ('a build command template with {cc}, {cflags} and {out} (and optionally '
              '{source}), such as "{cc} {cflags} {source} -o {out} -lm"')


def parse_programs(value: object, source: Path, taken: Sequence[str]
                    ) -> tuple[tuple[programs.Program, ...], dict[str, tuple[str, ...]]]:
    """`programs: {NAME: TEMPLATE}`, `{NAME: {command: TEMPLATE, check: TEMPLATE, source:
    PATH, build: TEMPLATE}}` or a class `{NAME: {glob: PATTERN, command: TEMPLATE}}` (one
    program per file matched, {path} and {dir} in the templates); the programs, and each
    class's program names."""
    raw = kinds.mapping(value, "programs", source)
    result = []
    classes: dict[str, tuple[str, ...]] = {}
    for name, entry in raw.items():
        label = f"programs.{name}"
        _check_new_name(name, label, taken, source)
        fields = {"command": entry} if isinstance(entry, str) else entry
        if not isinstance(fields, dict):
            raise config_error(source, label, PROGRAM_FORMS, entry)
        kinds.reject_unknown(fields, programs.PROGRAM_KEYS, f"{label}.", source)
        if "command" not in fields:
            raise config_error(source, f"{label}.command", "a command template", MISSING)
        extra = (programs.PATH, programs.DIR) if programs.GLOB in fields else ()
        for key, template in fields.items():
            where = label if isinstance(entry, str) else f"{label}.{key}"
            if key == programs.SOURCE:
                _check_source(template, where, source, extra)
                continue
            if not isinstance(template, str) or not template.strip():
                raise config_error(source, where, BUILD_FORM if key == programs.BUILD
                                   else PROGRAM_FORMS, template)
            if key == programs.GLOB:
                continue
            try:
                if key == programs.BUILD:
                    programs.check_placeholders(template, extra, programs.BUILD_PLACEHOLDERS,
                                                programs.BUILD_REQUIRED)
                else:
                    programs.check_placeholders(template, extra)
            except programs.TemplateError as exc:
                raise config_error(source, where, f"{BUILD_FORM}: {exc}" if key == programs.BUILD
                                   else f"a command template with {{input}} and optionally "
                                   f"{{threads}} and {{ranks}}: {exc}", template) from None
        for one, other in ((programs.SOURCE, programs.BUILD), (programs.BUILD, programs.SOURCE)):
            if one in fields and other not in fields:
                raise config_error(source, f"{label}.{other}", f"`{other}:` beside `{one}:` "
                                   "(the harness builds the program from its source)", MISSING)
        directory = source.resolve().parent
        if not extra:
            result.append(programs.from_mapping(name, fields, directory))
            continue
        members = programs.class_members(str(fields[programs.GLOB]), directory)
        if not members:
            raise config_error(source, f"{label}.glob", f"a pattern that matches files under "
                               f"{directory}", fields[programs.GLOB])
        for member, path in members:
            _check_new_name(member, f"{label}.glob ({path})",
                            (*taken, name, *(p.name for p in result)), source)
            result.append(programs.from_mapping(member, fields, directory, path))
        classes[name] = tuple(member for member, _ in members)
    return tuple(result), classes
