"""The document model written as HTML (Jinja2 and markdown-it-py) and Markdown, and read back
from the cache's JSON."""

from __future__ import annotations

from pathlib import Path

from harness.report.document import (
    Bullets,
    Details,
    Document,
    Figure,
    Link,
    Paragraph,
    Section,
    Table,
    from_json,
    image_size,
    render_html,
    render_markdown,
    to_json,
)

PNG_3x2 = bytes.fromhex(
    "89504e470d0a1a0a0000000d49484452000000030000000208060000009d74661a0000001149444154789c"
    "63f8cfc0f01f86199039009b7e0bf572b0b93c0000000049454e44ae426082")


def document(tmp_path: Path) -> Document:
    figure = tmp_path / "figures" / "a.png"
    figure.parent.mkdir()
    figure.write_bytes(PNG_3x2)
    (tmp_path / "figures" / "a.svg").write_text("<svg/>")
    table = Table(("variant", "median [s]"), (("p1", "1.5"), ("<b>", "2")), (False, True),
                  "Times of `p1`.")
    section = Section("Strategies", "strategies", (
        Paragraph("The **broad phase** of `p1`; see [the summary](#summary) & <script>."),
        Details("2 flagged cells", (table,), "strategies-warnings"),
        Figure(figure, "Time of *each* variant.", (tmp_path / "figures" / "a.svg",)),
        Bullets(("one `x`", "two")),
    ))
    summary = Section("Summary", "summary", (Bullets(("Best: `p1d`.",)),))
    return Document("collide-bench report", "Measured on **Box**.",
                    (Link("Other box", "machines/ab/report"),), summary, (section,))


def test_running_text_becomes_elements_and_nothing_is_interpreted(tmp_path: Path) -> None:
    page = render_html(document(tmp_path), tmp_path)
    assert "<strong>broad phase</strong> of <code>p1</code>" in page
    assert '<a href="#summary">the summary</a> &amp; &lt;script&gt;.' in page
    assert "<script>" not in page and "<td>&lt;b&gt;</td>" in page
    assert "<caption>Times of <code>p1</code>.</caption>" in page
    assert "<em>each</em>" in page and 'alt="Time of each variant."' in page
    assert "**" not in page and "`" not in page


def test_figures_are_linked_beside_the_page_with_their_size(tmp_path: Path) -> None:
    page = render_html(document(tmp_path), tmp_path)
    assert '<img src="figures/a.png" alt="Time of each variant." width="3" height="2">' in page
    assert '<a href="figures/a.svg">(SVG)</a>' in page
    assert image_size(tmp_path / "figures" / "a.png") == (3, 2)
    assert image_size(tmp_path / "figures" / "a.svg") is None


def test_folded_blocks_and_links_to_other_pages(tmp_path: Path) -> None:
    doc = document(tmp_path)
    page = render_html(doc, tmp_path)
    assert '<details id="strategies-warnings"><summary>2 flagged cells</summary>' in page
    assert '<a href="machines/ab/report.html">Other box</a>' in page
    markdown = render_markdown(doc, tmp_path)
    assert '<details id="strategies-warnings"><summary>2 flagged cells</summary>' in markdown
    assert "Other machines: [Other box](machines/ab/report.md)." in markdown
    assert "The **broad phase** of `p1`" in markdown  # report.md keeps the markup


def test_a_section_with_folded_blocks_survives_the_cache(tmp_path: Path) -> None:
    section = document(tmp_path).sections[0]
    assert from_json(to_json(section, tmp_path), tmp_path) == section
