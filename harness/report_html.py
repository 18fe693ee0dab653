"""The report as one self-contained HTML page: figures embedded as base64, styles inline.

Renders the document model of `harness.report` (Document, Section and blocks that carry a
`kind`: paragraph, bullets, table, figure). It dispatches on `kind` rather than importing the
classes, so it works the same whether report.py runs as a script or as `harness.report`.
"""

from __future__ import annotations

import base64
import html
import re
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from harness.report import Document, Section

MIME_TYPES: dict[str, str] = {".png": "image/png", ".gif": "image/gif", ".svg": "image/svg+xml"}
CODE_SPAN = re.compile(r"`([^`]+)`")

STYLE = """
body { font-family: system-ui, -apple-system, "Segoe UI", sans-serif; max-width: 72rem;
       margin: 2rem auto; padding: 0 1rem; color: #1d1d1f; line-height: 1.45; }
h1 { border-bottom: 2px solid #444; padding-bottom: .3rem; }
h2 { border-bottom: 1px solid #bbb; padding-bottom: .2rem; margin-top: 2.5rem; }
code { background: #f2f2f2; padding: 0 .25rem; border-radius: 3px; }
table { border-collapse: collapse; margin: .5rem 0 1.5rem; font-size: .9rem; }
caption { caption-side: top; text-align: left; font-style: italic; padding-bottom: .3rem; }
th, td { border: 1px solid #ccc; padding: .2rem .5rem; }
th { background: #f4f4f4; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
tbody tr:nth-child(even) { background: #fafafa; }
figure { margin: 1rem 0 2rem; }
figure img { max-width: 100%; height: auto; border: 1px solid #eee; }
figcaption { font-style: italic; font-size: .9rem; }
nav ul { columns: 2; }
"""


def inline(text: str) -> str:
    """Escape text and turn `code` spans into <code>."""
    return CODE_SPAN.sub(r"<code>\1</code>", html.escape(text))


def data_uri(path: Any) -> str:
    """The file's bytes as a data: URI, so the page needs nothing beside it."""
    mime = MIME_TYPES.get(path.suffix, "application/octet-stream")
    return f"data:{mime};base64,{base64.b64encode(path.read_bytes()).decode('ascii')}"


def _table(block: Any) -> str:
    header = "".join(f"<th>{html.escape(str(c))}</th>" for c in block.frame.columns)
    rows = []
    for values in block.frame.itertuples(index=False):
        cells = "".join(
            f'<td class="num">{html.escape(str(v))}</td>' if right
            else f"<td>{html.escape(str(v))}</td>"
            for v, right in zip(values, block.align_right, strict=True)
        )
        rows.append(f"<tr>{cells}</tr>")
    return (f"<table><caption>{inline(block.caption)}</caption><thead><tr>{header}</tr></thead>"
            f"<tbody>{''.join(rows)}</tbody></table>")


def _figure(block: Any) -> str:
    # The SVG is not embedded a second time: the PNG shows it; the files sit in figures/.
    return (f'<figure><img src="{data_uri(block.image)}" alt="{html.escape(block.caption)}">'
            f"<figcaption>{inline(block.caption)}</figcaption></figure>")


def render_block(block: Any) -> str:
    """One block as HTML."""
    if block.kind == "paragraph":
        return f"<p>{inline(block.text)}</p>"
    if block.kind == "bullets":
        return "<ul>" + "".join(f"<li>{inline(i)}</li>" for i in block.items) + "</ul>"
    if block.kind == "table":
        return _table(block)
    if block.kind == "figure":
        return _figure(block)
    raise ValueError(f"unknown block kind {block.kind!r}")


def _section(section: Section, level: int) -> list[str]:
    parts = [f'<h{level} id="{html.escape(section.anchor)}">{inline(section.title)}</h{level}>']
    parts += [render_block(b) for b in section.blocks]
    for sub in section.subsections:
        parts += _section(sub, level + 1)
    return parts


def _contents(doc: Document) -> str:
    items = "".join(
        f'<li><a href="#{html.escape(s.anchor)}">{inline(s.title)}</a></li>' for s in doc.sections
    )
    return f"<nav><h2>Contents</h2><ul>{items}</ul></nav>" if doc.sections else ""


def render_html(doc: Document) -> str:
    """The whole document as one HTML page."""
    body = [f"<h1>{inline(doc.title)}</h1>", *(render_block(b) for b in doc.preamble)]
    body.append(_contents(doc))
    for section in doc.sections:
        body += _section(section, 2)
    return (
        '<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
        f"<title>{html.escape(doc.title)}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n"
        + "\n".join(body)
        + "\n</body>\n</html>\n"
    )
