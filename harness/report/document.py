"""The report's document model, plain frozen data, and its two writers: report.md and
report.html.

Every block holds strings and paths only (a table is already formatted), so a section can be
written to JSON and read back unchanged: that is what lets an unchanged section be reused
instead of rebuilt (harness/report/cache.py).

Running text (paragraphs, bullets, captions, titles) is CommonMark inline markup: `code`,
**strong**, *emphasis* and [links](#anchor). report.md carries it as written; report.html is a
Jinja2 template (templates/report.html) that renders it with markdown-it-py, so the page shows
no markup characters. Table cells are plain text. The figures are files beside the page
(figures/), linked relatively, so the page stays small and works offline from a copy of the
report directory.
"""

from __future__ import annotations

import dataclasses
import functools
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, get_args

from markupsafe import Markup

if TYPE_CHECKING:
    import jinja2
    from markdown_it import MarkdownIt

TEMPLATES = Path(__file__).resolve().parent / "templates"


@dataclass(frozen=True)
class Paragraph:
    """Running text, in CommonMark inline markup."""

    text: str


@dataclass(frozen=True)
class Bullets:
    items: tuple[str, ...]


@dataclass(frozen=True)
class Table:
    """A formatted table: display headers, rows of display strings, and its caption."""

    columns: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]
    align_right: tuple[bool, ...]
    caption: str
    files: tuple[Path, ...] = ()  # the table as files (a CSV), linked after the caption


@dataclass(frozen=True)
class Figure:
    """An image file (PNG or GIF) with alternates (the SVG) and a caption."""

    image: Path
    caption: str
    alternates: tuple[Path, ...] = ()


@dataclass(frozen=True)
class Details:
    """Blocks folded away under a one-line plain-text summary (HTML's <details>), with an
    anchor a link can land on."""

    summary: str
    blocks: tuple[Paragraph | Bullets | Table | Figure, ...]
    anchor: str = ""


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


def kind(item: object) -> str:
    """"paragraph", "table", ...: what the JSON form and the templates call a block (or any
    other item)."""
    return type(item).__name__.lower()


def slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_-]+", "-", text).strip("-").lower() or "x"


def section_blocks(section: Section) -> list[Block]:
    """The blocks of a section and of all its subsections, folded ones included."""
    blocks: list[Block] = []
    for block in section.blocks:
        blocks += [block, *block.blocks] if isinstance(block, Details) else [block]
    for sub in section.subsections:
        blocks += section_blocks(sub)
    return blocks


def document_files(doc: Document) -> set[Path]:
    """Every figure file the document shows or links."""
    files: set[Path] = set()
    for section in (*([doc.summary] if doc.summary else []), *doc.sections, *doc.appendix):
        for block in section_blocks(section):
            if isinstance(block, Figure):
                files |= {block.image, *block.alternates}
            elif isinstance(block, Table):
                files |= set(block.files)
    return files


# --- JSON form, for the section cache (paths relative to the report directory) ------------

KINDS: dict[str, type] = {c.__name__.lower(): c for c in (*get_args(Block), Section)}
PATH_FIELDS = ("files", "image", "alternates")


def to_json(item: Any, base: Path) -> dict[str, object]:
    """A block, a section or any other dataclass of them (an experiment's part) as JSON with
    its kind, paths relative to `base`."""
    def value(v: object) -> object:
        if isinstance(v, Path):
            return v.relative_to(base).as_posix()
        if isinstance(v, tuple):
            return [value(x) for x in v]
        if isinstance(v, dict):
            return {k: value(x) for k, x in v.items()}
        return to_json(v, base) if dataclasses.is_dataclass(v) else v

    return {"kind": kind(item),
            **{f.name: value(getattr(item, f.name)) for f in dataclasses.fields(item)}}


def from_json(data: dict, base: Path, kinds: Mapping[str, type] = KINDS) -> Any:
    """What to_json wrote, its kinds those of `kinds`."""
    if data["kind"] not in kinds:
        raise ValueError(f"unknown block kind {data['kind']!r}")

    def value(name: str, v: object) -> object:
        if name in PATH_FIELDS:
            return base / v if isinstance(v, str) else tuple(base / p for p in v)  # type: ignore[attr-defined]
        if isinstance(v, list):
            return tuple(value("", x) for x in v)
        if isinstance(v, dict):
            return from_json(v, base, kinds) if "kind" in v else {
                k: value("", x) for k, x in v.items()}
        return v

    return kinds[data["kind"]](**{k: value(k, v) for k, v in data.items() if k != "kind"})


# --- report.md ------------------------------------------------------------------------------


def markdown_table(table: Table, out_dir: Path = Path()) -> list[str]:
    """The table's lines, after its caption and `([CSV](figures/x.csv))` for each of its files
    (relative to the page's directory)."""
    links = [f"([{p.suffix[1:].upper()}]({p.relative_to(out_dir).as_posix()}))"
             for p in table.files]
    caption = " ".join([f"*{table.caption}*"] * bool(table.caption) + links)
    lines = [caption, ""] if caption else []
    rule = ["---:" if right else "---" for right in table.align_right]
    for row in (table.columns, rule, *table.rows):
        cells = (v.replace("|", "\\|").replace("\n", " ") for v in row)
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def render_markdown(doc: Document, out_dir: Path) -> str:
    text = _environment().get_template("report.md").render(doc=doc, base=out_dir, suffix=".md")
    return text.rstrip() + "\n"


# --- report.html ----------------------------------------------------------------------------


@functools.cache
def _markdown() -> MarkdownIt:
    from markdown_it import MarkdownIt

    # CommonMark with raw HTML off: a `<` in the text is shown, never interpreted.
    return MarkdownIt("commonmark", {"html": False})


def inline(text: str) -> Markup:
    return Markup(_markdown().renderInline(text))


# A number's 95% interval after it (`0.0453 [0.0449, 0.0456]`): kept on one line, so that a
# narrow column breaks between the number and its interval, never inside either.
_INTERVAL = re.compile(r"^(.*?) (\[[^\[\]]*\])$")


def number(text: str) -> Markup:
    found = _INTERVAL.match(text)
    if found is None:
        return Markup.escape(text)
    return Markup('{} <span class="ci">{}</span>').format(found[1], found[2])


@functools.cache
def _environment() -> jinja2.Environment:
    import jinja2

    # report.md carries the text as written: only the HTML template escapes it.
    env = jinja2.Environment(loader=jinja2.FileSystemLoader(TEMPLATES),
                             autoescape=jinja2.select_autoescape(["html"]),
                             trim_blocks=True, lstrip_blocks=True,
                             undefined=jinja2.StrictUndefined)
    env.filters.update(inline=inline, number=number, kind=kind,
                       relative=lambda path, base: Path(path).relative_to(base).as_posix())
    env.globals.update(image_size=image_size, zip=zip, markdown_table=markdown_table)
    return env


def image_size(path: Path) -> tuple[int, int] | None:
    """A PNG's or GIF's width and height (so the page reserves their space before they load),
    or None for anything else."""
    from PIL import Image  # only here: importing this module stays light

    try:
        with Image.open(path) as image:  # reads the header only
            return image.size if image.format in ("PNG", "GIF") else None
    except OSError:  # not an image PIL knows (an SVG), or missing
        return None


def render_html(doc: Document, out_dir: Path) -> str:
    template = _environment().get_template("report.html")
    return template.render(doc=doc, base=Path(out_dir), suffix=".html")
