"""A self-contained HTML page: summary first, a contents list, captioned figures, tables.

The page has no script and no external resource (figures are inline PNG); its style keeps
every table within the page at 1280 px and in print (cells wrap, no fixed widths), and
keeps a figure with its caption on one printed page. Build it section by section::

    page = Page("ZIP fit of bus.csv")
    page.summary("<p>...</p>")
    sec = page.section("Load curves")
    sec.figure(png, "P(V) and Q(V) ...", alt="...")
    html = page.render()
"""

from __future__ import annotations

import base64
import html
import re
from collections.abc import Sequence
from dataclasses import dataclass, field

__all__ = ["CSS", "Page", "Section", "table_html"]

CSS = """
:root { color-scheme: light; }
* { box-sizing: border-box; }
body { font: 15px/1.5 system-ui, -apple-system, "Segoe UI", Roboto, sans-serif;
       color: #1b1f24; max-width: 1100px; margin: 0 auto; padding: 1.5rem 2rem 4rem; }
h1 { font-size: 1.7rem; margin: 0 0 .3rem; }
h2 { font-size: 1.3rem; margin-top: 2.2rem; border-bottom: 1px solid #d0d7de;
     padding-bottom: .2rem; }
h3 { font-size: 1.05rem; margin-top: 1.4rem; }
p.meta { color: #57606a; margin-top: 0; }
.summary { background: #f6f8fa; border: 1px solid #d0d7de; border-radius: 6px;
           padding: .6rem 1.2rem 1rem; }
.summary h2 { margin-top: .4rem; }
nav.contents ol { columns: 2; margin: .3rem 0; }
table { border-collapse: collapse; margin: .6rem 0 1rem; font-size: .86rem; }
table.wide { width: 100%; }
th, td { border-bottom: 1px solid #d0d7de; padding: .25rem .55rem; text-align: right;
         vertical-align: top; white-space: nowrap; }
thead th { white-space: normal; overflow-wrap: break-word; }
td.text, tbody th.text { white-space: normal; overflow-wrap: anywhere; }
th:first-child, td:first-child, td.text, th.text { text-align: left; }
thead th { background: #f6f8fa; font-weight: 600; }
td.flag { color: #a40e26; font-weight: 600; }
tr.flag td { background: #ffebe9; }
.warn { border-left: 4px solid #bf8700; background: #fff8c5; padding: .5rem .9rem;
        margin: .6rem 0; }
.ok { border-left: 4px solid #1a7f37; background: #dafbe1; padding: .5rem .9rem;
      margin: .6rem 0; }
figure { margin: 1rem 0 1.6rem; break-inside: avoid; page-break-inside: avoid; }
figure img { max-width: 100%; height: auto; display: block; border: 1px solid #eaeef2; }
figcaption { font-size: .9rem; color: #3d444d; margin-top: .35rem; }
figcaption b { color: #1b1f24; }
code { font-size: .85em; overflow-wrap: anywhere; }
dl.settings { display: grid; grid-template-columns: max-content 1fr; gap: .15rem 1rem;
              font-size: .88rem; }
dl.settings dt { font-weight: 600; }
dl.settings dd { margin: 0; overflow-wrap: anywhere; }
@media print {
  body { font-size: 10pt; max-width: 100%; padding: 0; }
  h2 { break-after: avoid; page-break-after: avoid; }
  table { font-size: 8pt; break-inside: auto; }
  th, td { padding: .15rem .3rem; }
  table.wide { font-size: 7pt; }
  tr { break-inside: avoid; page-break-inside: avoid; }
  nav.contents ol { columns: 2; }
  a { color: inherit; }
}
@page { size: A4; margin: 14mm; }
"""


def _slug(text: str) -> str:
    return re.sub(r"[^a-z0-9]+", "-", text.lower()).strip("-") or "section"


def table_html(
    header: Sequence[str],
    rows: Sequence[Sequence[str]],
    *,
    text_cols: Sequence[int] = (0,),
    flags: Sequence[bool] | None = None,
    caption: str | None = None,
    wide: bool = False,
) -> str:
    """An HTML table from already formatted cells (escaped here).

    Parameters
    ----------
    header : sequence of str
        Column titles.
    rows : sequence of sequences of str
        Cells, formatted (see :func:`loadbayes.core.display.fmt`).
    text_cols : sequence of int
        Columns aligned left (text); numbers are aligned right.
    flags : sequence of bool, optional
        Rows to highlight (e.g. a true value outside the interval).
    caption : str, optional
        Table caption.
    wide : bool
        Take the page's width, so that text cells wrap instead of pushing the table past
        the margin (tables of many columns).
    """
    e = html.escape
    head = "".join(
        f"<th scope='col'{' class=text' if i in text_cols else ''}>{e(h)}</th>"
        for i, h in enumerate(header)
    )
    body = []
    for k, row in enumerate(rows):
        flag = bool(flags[k]) if flags is not None else False
        cells = "".join(
            (f"<th scope='row'{' class=text' if i in text_cols else ''}>{e(c)}</th>" if i == 0 else
             f"<td{' class=text' if i in text_cols else ''}>{e(c)}</td>")
            for i, c in enumerate(row)
        )  # fmt: skip
        body.append(f"<tr{' class=flag' if flag else ''}>{cells}</tr>")
    cap = f"<caption>{e(caption)}</caption>" if caption else ""
    cls = " class='wide'" if wide else ""
    return f"<table{cls}>{cap}<thead><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody></table>"


@dataclass
class Section:
    """One section of the page: a heading, then HTML blocks and figures in order."""

    title: str
    blocks: list[str] = field(default_factory=list)
    figures: int = 0
    number: int = 0

    @property
    def anchor(self) -> str:
        """The section's id (for the contents list)."""
        return _slug(self.title)

    def add(self, fragment: str) -> Section:
        """Append raw HTML (already escaped)."""
        self.blocks.append(fragment)
        return self

    def text(self, paragraph: str) -> Section:
        """Append a paragraph of plain text (escaped here)."""
        return self.add(f"<p>{html.escape(paragraph)}</p>")

    def figure(self, png: bytes, caption: str, *, alt: str, title: str | None = None) -> Section:
        """Append a PNG figure inline, with a numbered caption and alt text."""
        self.figures += 1
        data = base64.b64encode(png).decode("ascii")
        head = f"<b>{html.escape(title)}.</b> " if title else ""
        self.blocks.append(
            f"<figure><img src='data:image/png;base64,{data}' alt='{html.escape(alt, True)}'>"
            f"<figcaption>{head}{html.escape(caption)}</figcaption></figure>"
        )
        return self


@dataclass
class Page:
    """A report page: title, a summary box first, a contents list, then sections."""

    title: str
    subtitle: str = ""
    summary_html: str = ""
    sections: list[Section] = field(default_factory=list)

    def summary(self, fragment: str) -> Page:
        """Set the summary box (HTML) shown first, before the contents."""
        self.summary_html = fragment
        return self

    def section(self, title: str) -> Section:
        """Start a new section and return it."""
        sec = Section(title, number=len(self.sections) + 1)
        self.sections.append(sec)
        return sec

    def render(self) -> str:
        """The whole page as one HTML string."""
        e = html.escape
        figure_no = 0
        parts = []
        for sec in self.sections:
            blocks = []
            for b in sec.blocks:
                if b.startswith("<figure>"):
                    figure_no += 1
                    b = b.replace("<figcaption>", f"<figcaption>Figure {figure_no}. ", 1)
                blocks.append(b)
            parts.append(
                f"<section id='{sec.anchor}'><h2>{sec.number}. {e(sec.title)}</h2>"
                + "".join(blocks)
                + "</section>"
            )
        toc = "".join(f"<li><a href='#{s.anchor}'>{e(s.title)}</a></li>" for s in self.sections)
        return (
            "<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>"
            "<meta name='viewport' content='width=device-width, initial-scale=1'>"
            f"<title>{e(self.title)}</title><style>{CSS}</style></head><body>"
            f"<header><h1>{e(self.title)}</h1>"
            + (f"<p class='meta'>{e(self.subtitle)}</p>" if self.subtitle else "")
            + "</header>"
            + (
                f"<section class='summary' id='summary'><h2>Summary</h2>{self.summary_html}"
                "</section>"
                if self.summary_html
                else ""
            )  # fmt: skip
            + f"<nav class='contents' aria-label='Contents'><h2>Contents</h2><ol>{toc}</ol></nav>"
            + "".join(parts)
            + "</body></html>\n"
        )
