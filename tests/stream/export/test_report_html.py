"""Tests of stream/export/report_html.py: the report as one self-contained HTML page."""

import base64

import pytest

from livedic.stream.export.report_html import report_html

PNG = b"\x89PNG\r\n\x1a\nfake"


def test_tables_become_html_and_images_are_embedded():
    text = "# Title\n\n| a | b |\n|---|---|\n| 1 | 2 |\n\n![plot](plot.png)\n"
    page = report_html(text, {"plot.png": PNG}, "my <test>")
    assert page.startswith("<!DOCTYPE html>") and "<title>my &lt;test&gt;</title>" in page
    assert "<table>" in page and "<td>1</td>" in page
    assert f"data:image/png;base64,{base64.b64encode(PNG).decode()}" in page and 'src="plot.png"' not in page
    assert "@page" in page                   # a print style: it prints on A4


def test_an_image_the_page_cannot_embed_is_an_error_not_a_broken_picture():
    with pytest.raises(KeyError):
        report_html("![plot](missing.png)", {}, "t")
