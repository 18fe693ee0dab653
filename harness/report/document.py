"""The report's document model: plain frozen data that Markdown and HTML both render.

Every block holds strings and paths only (a table is already formatted), so a section can be
written to JSON and read back unchanged: that is what lets an unchanged section be reused
instead of rebuilt (harness/report/cache.py). Standard library only.

Running text (paragraphs, bullets, captions, titles) is CommonMark inline markup: `code`,
**strong**, *emphasis* and [links](#anchor). report.md carries it as written; the HTML writer
renders it with markdown-it-py, so the page shows no markup characters. Table cells are plain
text.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar


@dataclass(frozen=True)
class Paragraph:
    """Running text, in CommonMark inline markup."""

    text: str
    kind: ClassVar[str] = "paragraph"


@dataclass(frozen=True)
class Bullets:
    items: tuple[str, ...]
    kind: ClassVar[str] = "bullets"


@dataclass(frozen=True)
class Table:
    """A formatted table: display headers, rows of display strings, and its caption."""

    columns: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]
    align_right: tuple[bool, ...]
    caption: str
    files: tuple[Path, ...] = ()  # the table as files (a CSV), linked after the caption
    kind: ClassVar[str] = "table"


@dataclass(frozen=True)
class Figure:
    """An image file (PNG or GIF) with alternates (the SVG) and a caption."""

    image: Path
    caption: str
    alternates: tuple[Path, ...] = ()
    kind: ClassVar[str] = "figure"


@dataclass(frozen=True)
class Details:
    """Blocks folded away under a one-line plain-text summary (HTML's <details>), with an
    anchor a link can land on."""

    summary: str
    blocks: tuple[Paragraph | Bullets | Table | Figure, ...]
    anchor: str = ""
    kind: ClassVar[str] = "details"


Block = Paragraph | Bullets | Table | Figure | Details


@dataclass(frozen=True)
class Section:
    title: str
    anchor: str
    blocks: tuple[Block, ...]
    subsections: tuple[Section, ...] = ()


@dataclass(frozen=True)
class Link:
    """A link to another report page (another machine's): its path relative to this page,
    without the suffix, which each writer adds (report.md links report.md, report.html links
    report.html)."""

    text: str
    stem: str


@dataclass(frozen=True)
class Document:
    """A report page: under the title a line naming what it shows (`lead`) and links to its
    sibling pages (`others`), then the summary, the sections, and what the reader consults
    only on occasion (`appendix`)."""

    title: str
    lead: str = ""
    others: tuple[Link, ...] = ()
    summary: Section | None = None  # the headline, shown first, right under the title
    sections: tuple[Section, ...] = field(default_factory=tuple)
    appendix: tuple[Section, ...] = ()


def slug(text: str) -> str:
    """A file-name and anchor-safe form of a name."""
    return re.sub(r"[^A-Za-z0-9_-]+", "-", text).strip("-").lower() or "x"


def section_blocks(section: Section) -> list[Block]:
    """The blocks of a section and of all its subsections, folded ones included."""
    blocks: list[Block] = []
    for block in section.blocks:
        blocks += [block, *block.blocks] if isinstance(block, Details) else [block]
    for sub in section.subsections:
        blocks += section_blocks(sub)
    return blocks


def document_sections(doc: Document) -> list[Section]:
    """The document's top-level sections in reading order."""
    return [*([doc.summary] if doc.summary else []), *doc.sections, *doc.appendix]


def document_files(doc: Document) -> set[Path]:
    """Every figure file the document shows or links."""
    files: set[Path] = set()
    for section in document_sections(doc):
        for block in section_blocks(section):
            if isinstance(block, Figure):
                files |= {block.image, *block.alternates}
            elif isinstance(block, Table):
                files |= set(block.files)
    return files


# --- JSON form, for the section cache (paths relative to the report directory) ------------


def block_to_json(block: Block, base: Path) -> dict[str, object]:
    if isinstance(block, Details):
        return {"kind": block.kind, "summary": block.summary, "anchor": block.anchor,
                "blocks": [block_to_json(b, base) for b in block.blocks]}
    if isinstance(block, Paragraph):
        return {"kind": block.kind, "text": block.text}
    if isinstance(block, Bullets):
        return {"kind": block.kind, "items": list(block.items)}
    if isinstance(block, Table):
        return {"kind": block.kind, "columns": list(block.columns),
                "rows": [list(r) for r in block.rows], "align_right": list(block.align_right),
                "caption": block.caption,
                "files": [p.relative_to(base).as_posix() for p in block.files]}
    return {"kind": block.kind, "image": block.image.relative_to(base).as_posix(),
            "caption": block.caption,
            "alternates": [p.relative_to(base).as_posix() for p in block.alternates]}


def block_from_json(data: dict, base: Path) -> Block:
    kind = data["kind"]
    if kind == Paragraph.kind:
        return Paragraph(data["text"])
    if kind == Bullets.kind:
        return Bullets(tuple(data["items"]))
    if kind == Table.kind:
        return Table(tuple(data["columns"]), tuple(tuple(r) for r in data["rows"]),
                     tuple(data["align_right"]), data["caption"],
                     tuple(base / p for p in data.get("files", ())))
    if kind == Figure.kind:
        return Figure(base / data["image"], data["caption"],
                      tuple(base / p for p in data["alternates"]))
    if kind == Details.kind:
        inner = tuple(block_from_json(b, base) for b in data["blocks"])
        return Details(data["summary"], inner, data["anchor"])  # type: ignore[arg-type]
    raise ValueError(f"unknown block kind {kind!r}")


def section_to_json(section: Section, base: Path) -> dict[str, object]:
    return {"title": section.title, "anchor": section.anchor,
            "blocks": [block_to_json(b, base) for b in section.blocks],
            "subsections": [section_to_json(s, base) for s in section.subsections]}


def section_from_json(data: dict, base: Path) -> Section:
    return Section(data["title"], data["anchor"],
                   tuple(block_from_json(b, base) for b in data["blocks"]),
                   tuple(section_from_json(s, base) for s in data["subsections"]))
