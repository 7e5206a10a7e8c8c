"""MkDocs hooks: the guide is written for GitHub (GFM); these make MkDocs' Markdown read it the same way.

- Links to files of the repository outside docs/guide/ (``../../recordings/README.md``): GitHub follows
  them; the built site holds only the guide, so there such a link becomes the file's path, as code. A
  link to a file the repository does not have is a warning, which ``mkdocs build --strict``
  (tests/test_docs.py) fails on, as it does for broken links inside the guide.
- List items: GFM indents an item's later paragraphs, tables and code by the width of its marker ("- ",
  2 columns); Python-Markdown wants 4. Those lines get 2 more spaces, so they stay in their item.
- Table cells: GFM needs a ``|`` inside code escaped as ``\\|``; Python-Markdown already leaves pipes in
  code alone and would show the backslash.
"""
import logging
import re
from pathlib import Path

log = logging.getLogger("mkdocs.hooks.repository_links")
_LINK = re.compile(r"\[([^\]]+)\]\(([^)\s#]+)(#[^)\s]*)?\)")


def on_page_markdown(markdown, page, config, files):
    markdown = _unescape_table_code(_indent_list_items(markdown))
    return _repository_links(markdown, page, config)


def _indent_list_items(markdown: str) -> str:
    """Give the indented lines of a top-level "- " item 4 columns of indent, not GFM's 2.

    An item that holds several blocks is followed by a blank line before the next item: without one,
    Python-Markdown reads the next item as more of the last block's text.
    """
    lines, in_item, blocks = [], False, False
    for line in markdown.split("\n"):
        if line.startswith("- "):
            if in_item and blocks and lines[-1].strip():
                lines.append("")
            in_item, blocks = True, False
        elif line.strip() and not line.startswith(" "):
            in_item = False
        elif in_item and not line.strip():
            blocks = True
        elif in_item and line.startswith("  "):
            line = "  " + line
        lines.append(line)
    return "\n".join(lines)


_CODE = re.compile(r"`[^`\n]*`")


def _unescape_table_code(markdown: str) -> str:
    lines = [_CODE.sub(lambda m: m.group(0).replace("\\|", "|"), line) if line.lstrip().startswith("|") else line
             for line in markdown.split("\n")]
    return "\n".join(lines)


def _repository_links(markdown, page, config):
    docs = Path(config["docs_dir"]).resolve()
    repository = docs.parent.parent
    here = (docs / page.file.src_path).parent

    def outside(match: re.Match) -> str:
        text, target = match.group(1), match.group(2)
        if "://" in target or target.startswith(("mailto:", "/")):
            return match.group(0)
        path = (here / target).resolve()
        if path.is_relative_to(docs):
            return match.group(0)  # MkDocs checks these itself
        if not path.is_relative_to(repository) or not path.exists():
            log.warning("Doc file '%s' links to '%s', which is not a file of the repository",
                        page.file.src_path, target)
            return match.group(0)
        name = path.relative_to(repository).as_posix()
        return f"`{name}`" if text.strip("`") == name else f"{text} (`{name}`)"

    return _LINK.sub(outside, markdown)
