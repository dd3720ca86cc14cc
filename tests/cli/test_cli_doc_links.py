"""The repository stands alone: every markdown link and every `docs/...` page named in
code, comments, help texts or config resolves inside it; nothing points outside it."""

from __future__ import annotations

import re
import subprocess

import pytest
from support.paths import ROOT

TEXT_SUFFIXES = {".py", ".md", ".toml", ".conf", ".txt", ".cfg", ".example", ""}


def tracked_text_files() -> list[str]:
    files = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True).stdout.split()
    out = []
    for f in files:
        path = ROOT / f
        if path.suffix in TEXT_SUFFIXES and path.is_file():
            try:
                path.read_text(encoding="utf-8")
            except UnicodeDecodeError:
                continue
            out.append(f)
    return out


def markdown_links() -> list[tuple[str, str]]:
    links = []
    for f in tracked_text_files():
        if f.endswith(".md"):
            for target in re.findall(r"\]\(([^)\s]+)\)", (ROOT / f).read_text()):
                if not re.match(r"[a-z]+:", target) and not target.startswith("#"):
                    links.append((f, target.split("#", 1)[0]))
    return links


def named_docs_pages() -> list[tuple[str, str]]:
    pages = []
    for f in tracked_text_files():
        for page in re.findall(r"(?<![\w./-])(docs/[\w./-]+\.md)", (ROOT / f).read_text()):
            pages.append((f, page))
    return pages


#: a path outside the repository: the spec folder beside it, or the machine's work tree
OUTSIDE = re.compile(r"\.\./shared|(?<![\w/])spec/[\w-]+\.md|(?<![\w.])/" + "work/")


def test_nothing_points_outside_the_repository():
    offenders = []
    for f in tracked_text_files():
        for n, line in enumerate((ROOT / f).read_text().splitlines(), 1):
            if OUTSIDE.search(line):
                offenders.append(f"{f}:{n}: {line.strip()}")
    assert not offenders, "\n".join(offenders)


@pytest.mark.parametrize(("source", "target"), markdown_links())
def test_markdown_link_resolves(source, target):
    assert ((ROOT / source).parent / target).resolve().exists(), f"{source}: link to {target}"


@pytest.mark.parametrize(("source", "page"), sorted(set(named_docs_pages())))
def test_named_docs_page_exists(source, page):
    assert (ROOT / page).is_file(), f"{source} names {page}"


def test_every_protocol_page_is_linked_from_the_index():
    index = (ROOT / "docs" / "protocols" / "README.md").read_text()
    for page in (ROOT / "docs" / "protocols").glob("*.md"):
        if page.name != "README.md":
            assert f"]({page.name})" in index, page.name
