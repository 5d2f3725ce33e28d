"""What a reader meets: a README of one screenful (the rest in docs/ topic pages), and no link or
image in README.md or docs/*.md that leads nowhere."""
import re
from pathlib import Path
from urllib.parse import unquote

import pytest

ROOT = Path(__file__).resolve().parents[2]
README_MAX_LINES = 160
PAGES = [ROOT / "README.md"] + sorted((ROOT / "docs").glob("*.md"))
LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")
FENCE = re.compile(r"^```.*?^```", re.S | re.M)


def links(text: str) -> list:
    """The targets of markdown links and images, outside fenced code and inline code."""
    text = FENCE.sub("", text)
    text = re.sub(r"`[^`\n]*`", "", text)
    return LINK.findall(text)


def test_the_readme_is_one_screenful():
    n = len((ROOT / "README.md").read_text().splitlines())
    assert n <= README_MAX_LINES, f"README.md has {n} lines (at most {README_MAX_LINES}): move detail into docs/"


def test_the_readme_says_where_to_read_more():
    text = (ROOT / "README.md").read_text()
    for page in ("docs/results.md", "docs/performance.md", "docs/troubleshooting.md", "docs/architecture.md",
                 "docs/api.md", "sitl/README.md"):
        assert f"]({page})" in text, page


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_relative_link_and_image_resolves(page):
    bad = []
    for target in links(page.read_text()):
        if re.match(r"^[a-z][a-z0-9+.-]*:", target) or target.startswith("#"):
            continue  # a web address or an anchor on the same page
        path = unquote(target.split("#", 1)[0])
        if not (page.parent / path).exists():
            bad.append(target)
    assert not bad, f"{page.relative_to(ROOT)}: links to nothing: {bad}"


def test_the_link_finder_sees_links_and_images_but_not_code():
    text = "see [a](x.md) and ![img](y/z.png)\n```\n[not](code.md)\n```\n`[inline](no.md)` [b](c.md#part)\n"
    assert links(text) == ["x.md", "y/z.png", "c.md#part"]
