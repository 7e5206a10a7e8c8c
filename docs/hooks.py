"""MkDocs hook: the guide's links to files of the repository outside docs/guide/.

GitHub follows a link such as ``../../recordings/README.md``; the built site holds only the guide, so
there such a link becomes the file's path, as code. A link to a file the repository does not have is a
warning, which ``mkdocs build --strict`` (tests/test_docs.py) fails on, as it does for broken links
inside the guide.
"""
import logging
import re
from pathlib import Path

log = logging.getLogger("mkdocs.hooks.repository_links")
_LINK = re.compile(r"\[([^\]]+)\]\(([^)\s#]+)(#[^)\s]*)?\)")


def on_page_markdown(markdown, page, config, files):
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
