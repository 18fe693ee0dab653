"""The document model as Markdown (report.md). Standard library only."""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

from harness.report.document import Block, Bullets, Details, Document, Paragraph, Section, Table

SUFFIX = ".md"


def _md_cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def file_links(paths: Iterable[Path], out_dir: Path) -> str:
    """`([CSV](figures/x.csv))` for each file, relative to the page's directory."""
    return " ".join(f"([{p.suffix[1:].upper()}]({p.relative_to(out_dir).as_posix()}))"
                    for p in paths)


def markdown_table(table: Table, out_dir: Path | None = None) -> list[str]:
    header = [_md_cell(c) for c in table.columns]
    rule = ["---:" if right else "---" for right in table.align_right]
    links = file_links(table.files, out_dir) if out_dir is not None else ""
    caption = f"*{table.caption}* {links}".rstrip() if table.caption else links
    lines = [caption, ""] if caption else []
    lines += ["| " + " | ".join(header) + " |", "| " + " | ".join(rule) + " |"]
    for row in table.rows:
        lines.append("| " + " | ".join(_md_cell(v) for v in row) + " |")
    return lines


def markdown_blocks(blocks: Iterable[Block], out_dir: Path) -> list[str]:
    lines: list[str] = []
    for block in blocks:
        if isinstance(block, Details):
            # GitHub and most viewers fold it; the blank lines let the Markdown inside render.
            anchor = f' id="{block.anchor}"' if block.anchor else ""
            lines += [f"<details{anchor}><summary>{block.summary}</summary>", ""]
            lines += markdown_blocks(block.blocks, out_dir)
            lines.append("</details>")
        elif isinstance(block, Paragraph):
            lines.append(block.text)
        elif isinstance(block, Bullets):
            lines.extend(f"- {item}" for item in block.items)
        elif isinstance(block, Table):
            lines.extend(markdown_table(block, out_dir))
        else:
            image = block.image.relative_to(out_dir).as_posix()
            links = file_links(block.alternates, out_dir)
            lines.append(f"![{block.caption}]({image})")
            lines.append("")
            lines.append(f"*{block.caption}* {links}".rstrip())
        lines.append("")
    return lines


def _section(section: Section, level: int, out_dir: Path) -> list[str]:
    # An explicit anchor, so that the summary's links land on the same ids in Markdown as in
    # HTML; Markdown viewers derive their own ids from the heading text, which repeats.
    lines = [f'<a id="{section.anchor}"></a>', "", f"{'#' * level} {section.title}", "",
             *markdown_blocks(section.blocks, out_dir)]
    for sub in section.subsections:
        lines += _section(sub, level + 1, out_dir)
    return lines


def render_markdown(doc: Document, out_dir: Path) -> str:
    lines = [f"# {doc.title}", ""]
    if doc.lead:
        lines += [doc.lead, ""]
    if doc.others:
        links = ", ".join(f"[{link.text}]({link.stem}{SUFFIX})" for link in doc.others)
        lines += [f"Other machines: {links}.", ""]
    if doc.summary is not None:
        lines += _section(doc.summary, 2, out_dir)
    for section in (*doc.sections, *doc.appendix):
        lines += _section(section, 2, out_dir)
    return "\n".join(lines).rstrip() + "\n"
