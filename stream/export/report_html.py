"""``report.html``: the report as one self-contained document a person opens in a browser and prints.

The page is ``report.md`` turned into HTML by Python-Markdown (tables extension), with every image the text
links to embedded as a ``data:`` URI, and a style sheet for the screen and for A4 paper; it needs no other
file, so it can be mailed or archived alone. docs/guide/tensile-test.md shows it.
"""

from __future__ import annotations

import base64
import html
import re
from collections.abc import Mapping

import markdown

_STYLE = """
body { font-family: "DejaVu Sans", Helvetica, Arial, sans-serif; font-size: 10.5pt; color: #111;
       max-width: 190mm; margin: 12mm auto; line-height: 1.35; }
h1 { font-size: 17pt; border-bottom: 2px solid #333; padding-bottom: 3pt; }
h2 { font-size: 12.5pt; margin-top: 14pt; border-bottom: 1px solid #bbb; }
table { border-collapse: collapse; width: 100%; margin: 4pt 0 8pt; page-break-inside: avoid; }
th, td { border: 1px solid #bbb; padding: 2pt 5pt; vertical-align: top; text-align: left; }
th { background: #eee; }
td:first-child { min-width: 38mm; }
img { max-width: 100%; page-break-inside: avoid; }
code { font-size: 9.5pt; }
.signature { margin-top: 18pt; display: flex; gap: 24pt; page-break-inside: avoid; }
.signature div { flex: 1; border-top: 1px solid #333; padding-top: 3pt; font-size: 9pt; color: #444; }
@page { size: A4; margin: 14mm; }
@media print { body { margin: 0; max-width: none; } }
"""

_IMAGE = re.compile(r'(<img\b[^>]*\bsrc=")([^"]+)(")')


def report_html(markdown_text: str, images: Mapping[str, bytes], title: str) -> str:
    """The HTML document of ``markdown_text`` with ``images`` (file name -> PNG bytes) embedded.

    Raises
    ------
    KeyError
        The text links an image that ``images`` does not hold (the page would show a broken image).
    """
    body = markdown.markdown(markdown_text, extensions=["tables"], output_format="html")

    def embed(match: re.Match[str]) -> str:
        data = base64.b64encode(images[html.unescape(match.group(2))]).decode("ascii")
        return f"{match.group(1)}data:image/png;base64,{data}{match.group(3)}"

    body = _IMAGE.sub(embed, body)
    signature = ('<div class="signature"><div>tested by (name, date, signature)</div>'
                 '<div>checked by (name, date, signature)</div></div>')
    return ("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
            f"<title>{html.escape(title)}</title>\n<style>{_STYLE}</style>\n</head>\n<body>\n"
            f"{body}\n{signature}\n</body>\n</html>\n")
