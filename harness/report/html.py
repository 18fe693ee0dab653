"""The report as one self-contained HTML page: figures embedded as base64, styles inline.
Standard library only."""

from __future__ import annotations

import base64
import html
import re
from pathlib import Path

from harness.report.document import Block, Bullets, Document, Figure, Paragraph, Section, Table

MIME_TYPES: dict[str, str] = {".png": "image/png", ".gif": "image/gif", ".svg": "image/svg+xml"}
CODE_SPAN = re.compile(r"`([^`]+)`")
# [text](#anchor): a link within the page (the summary's links to its sections).
ANCHOR_LINK = re.compile(r"\[([^\]]+)\]\(#([A-Za-z0-9_-]+)\)")

STYLE = """
body { font-family: system-ui, -apple-system, "Segoe UI", sans-serif; max-width: 72rem;
       margin: 2rem auto; padding: 0 1rem; color: #1d1d1f; line-height: 1.45; }
h1 { border-bottom: 2px solid #444; padding-bottom: .3rem; }
h2 { border-bottom: 1px solid #bbb; padding-bottom: .2rem; margin-top: 2.5rem; }
code { background: #f2f2f2; padding: 0 .25rem; border-radius: 3px; overflow-wrap: anywhere; }
.table-wrap { overflow-x: auto; max-width: 100%; margin: .5rem 0 1.5rem; }
table { border-collapse: collapse; font-size: .9rem; }
caption { caption-side: top; text-align: left; font-style: italic; padding-bottom: .3rem; }
th, td { border: 1px solid #ccc; padding: .2rem .5rem; }
th { background: #f4f4f4; }
td.num { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
tbody tr:nth-child(even) { background: #fafafa; }
figure { margin: 1rem 0 2rem; }
figure img { max-width: 100%; height: auto; border: 1px solid #eee; }
figcaption { font-style: italic; font-size: .9rem; }
nav ul { columns: 2; }
.summary { background: #f6f8fa; border-left: 4px solid #3b6ea5; padding: .2rem 1rem; }
"""


def inline(text: str) -> str:
    """Escape text and turn `code` spans into <code>, [text](#anchor) into links."""
    escaped = CODE_SPAN.sub(r"<code>\1</code>", html.escape(text))
    return ANCHOR_LINK.sub(r'<a href="#\2">\1</a>', escaped)


def data_uri(path: Path) -> str:
    """The file's bytes as a data: URI, so the page needs nothing beside it."""
    mime = MIME_TYPES.get(path.suffix, "application/octet-stream")
    return f"data:{mime};base64,{base64.b64encode(path.read_bytes()).decode('ascii')}"


def _table(block: Table) -> str:
    header = "".join(f"<th>{html.escape(c)}</th>" for c in block.columns)
    rows = []
    for values in block.rows:
        cells = "".join(
            f'<td class="num">{html.escape(v)}</td>' if right else f"<td>{html.escape(v)}</td>"
            for v, right in zip(values, block.align_right, strict=True)
        )
        rows.append(f"<tr>{cells}</tr>")
    # The wrapper scrolls a wide table on its own instead of widening the whole page.
    return (f'<div class="table-wrap"><table><caption>{inline(block.caption)}</caption>'
            f"<thead><tr>{header}</tr></thead><tbody>{''.join(rows)}</tbody></table></div>")


def _figure(block: Figure) -> str:
    # The SVG is not embedded a second time: the PNG shows it; the files sit in figures/.
    return (f'<figure><img src="{data_uri(block.image)}" alt="{html.escape(block.caption)}">'
            f"<figcaption>{inline(block.caption)}</figcaption></figure>")


def render_block(block: Block) -> str:
    """One block as HTML."""
    if isinstance(block, Paragraph):
        return f"<p>{inline(block.text)}</p>"
    if isinstance(block, Bullets):
        return "<ul>" + "".join(f"<li>{inline(i)}</li>" for i in block.items) + "</ul>"
    if isinstance(block, Table):
        return _table(block)
    return _figure(block)


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
    body = [f"<h1>{inline(doc.title)}</h1>"]
    if doc.summary is not None:
        body += ['<div class="summary">', *_section(doc.summary, 2), "</div>"]
    body += [render_block(b) for b in doc.preamble]
    body.append(_contents(doc))
    for section in doc.sections:
        body += _section(section, 2)
    return (
        '<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
        '<meta name="viewport" content="width=device-width, initial-scale=1">\n'
        f"<title>{html.escape(doc.title)}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n"
        + "\n".join(body)
        + "\n</body>\n</html>\n"
    )
