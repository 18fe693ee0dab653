"""The document model as one HTML page (report.html): a Jinja2 template
(templates/report.html) fills in the blocks, markdown-it-py renders their running text. The
figures are files beside the page (figures/), linked relatively, so the page stays small and
works offline from a copy of the report directory."""

from __future__ import annotations

import functools
import re
from pathlib import Path

import jinja2
from markdown_it import MarkdownIt
from markupsafe import Markup

from harness.report.document import Document, kind

SUFFIX = ".html"
TEMPLATES = Path(__file__).resolve().parent / "templates"
PAGE_TEMPLATE = "report.html"


@functools.cache
def _markdown() -> MarkdownIt:
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
    env = jinja2.Environment(loader=jinja2.FileSystemLoader(TEMPLATES), autoescape=True,
                             trim_blocks=True, lstrip_blocks=True,
                             undefined=jinja2.StrictUndefined)
    env.filters["inline"] = inline
    env.filters["number"] = number
    env.filters["kind"] = kind
    env.filters["relative"] = lambda path, base: Path(path).relative_to(base).as_posix()
    env.globals["image_size"] = image_size
    env.globals["zip"] = zip
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
    template = _environment().get_template(PAGE_TEMPLATE)
    return template.render(doc=doc, base=Path(out_dir), suffix=SUFFIX)
