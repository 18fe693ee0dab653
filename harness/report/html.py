"""The document model as one HTML page (report.html): a Jinja2 template
(templates/report.html) fills in the blocks, markdown-it-py renders their running text. The
figures are files beside the page (figures/), linked relatively, so the page stays small and
works offline from a copy of the report directory."""

from __future__ import annotations

import functools
import struct
from pathlib import Path

import jinja2
from markdown_it import MarkdownIt
from markupsafe import Markup

from harness.report.document import Document

SUFFIX = ".html"
TEMPLATES = Path(__file__).resolve().parent / "templates"
PAGE_TEMPLATE = "report.html"


@functools.cache
def _markdown() -> MarkdownIt:
    # CommonMark with raw HTML off: a `<` in the text is shown, never interpreted.
    return MarkdownIt("commonmark", {"html": False})


def inline(text: str) -> Markup:
    return Markup(_markdown().renderInline(text))


@functools.cache
def _environment() -> jinja2.Environment:
    env = jinja2.Environment(loader=jinja2.FileSystemLoader(TEMPLATES), autoescape=True,
                             trim_blocks=True, lstrip_blocks=True,
                             undefined=jinja2.StrictUndefined)
    env.filters["inline"] = inline
    env.filters["kind"] = lambda block: block.kind
    env.filters["relative"] = lambda path, base: Path(path).relative_to(base).as_posix()
    env.globals["image_size"] = image_size
    env.globals["zip"] = zip
    return env


def image_size(path: Path) -> tuple[int, int] | None:
    """A PNG's or GIF's width and height from its header (so the page reserves their space
    before they load), or None for anything else."""
    try:
        with Path(path).open("rb") as handle:
            head = handle.read(24)
    except OSError:
        return None
    if head[:8] == b"\x89PNG\r\n\x1a\n" and head[12:16] == b"IHDR":
        width, height = struct.unpack(">II", head[16:24])
        return int(width), int(height)
    if head[:6] in (b"GIF87a", b"GIF89a"):
        width, height = struct.unpack("<HH", head[6:10])
        return int(width), int(height)
    return None


def render_html(doc: Document, out_dir: Path) -> str:
    """The whole document as one HTML page written into `out_dir` (figures linked relative to
    it)."""
    template = _environment().get_template(PAGE_TEMPLATE)
    return template.render(doc=doc, base=Path(out_dir), suffix=SUFFIX)
