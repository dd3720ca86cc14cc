"""The repository stands alone: every markdown link and every `docs/...` page named in
code, comments, help texts or config resolves inside it, a link's `#anchor` names a heading of
its page, every file of the repository the README and docs/ name (`config/sim/clean.toml`,
`tests/daq/test_can_link_loss.py`, `bench/*.py`) is there; nothing points outside it."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

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


def heading_anchors(markdown: str) -> set[str]:
    """The anchors GitHub gives the headings of ``markdown`` (lower case, punctuation dropped but
    hyphens, spaces to hyphens); a `#` line inside a code block is no heading."""
    anchors, fenced = set(), False
    for line in markdown.split("\n"):
        fenced ^= line.startswith("```")
        head = re.match(r"#+ (.+)", line)
        if head and not fenced:
            anchors.add(re.sub(r"[^\w\- ]", "", head.group(1).strip().lower()).replace(" ", "-"))
    return anchors


def anchored_links(source: Path) -> list[tuple[Path, str]]:
    """(page, anchor) of every link of ``source`` with a `#anchor` to a markdown page (itself included)."""
    links = []
    for target in re.findall(r"\]\(([^)\s]*#[^)\s]+)\)", source.read_text()):
        page, anchor = target.split("#", 1)
        if not re.match(r"[a-z]+:", page) and (not page or page.endswith(".md")):
            links.append(((source.parent / page).resolve() if page else source, anchor))
    return links


#: the folders of the repository whose files the README and docs/ name by path
NAMED_FOLDERS = (
    "bench",
    "config",
    "docs",
    "examples",
    "tests",
    "tools",
    "orbitrig",
    "daq",
    "drives",
    "reduction",
    "sim",
)
_NAMED_PATH = re.compile(
    rf"(?<![\w/.<-])((?:{'|'.join(NAMED_FOLDERS)})/[\w./*-]*\.(?:md|py|toml|csv|json|png|ipynb|conf))(?![\w/])"
)


def named_paths(text: str) -> set[str]:
    """The repository files (or globs) ``text`` names by path: `config/sim/clean.toml`, `bench/*.py`."""
    return set(_NAMED_PATH.findall(text))


def readme_and_docs() -> list[str]:
    return [f for f in tracked_text_files() if f in ("README.md", "CONTRIBUTING.md") or re.match(r"docs/.+\.md$", f)]


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


@pytest.mark.parametrize("source", readme_and_docs())
def test_link_anchor_names_a_heading_of_its_page(source):
    broken = [
        f"#{anchor} in {page.relative_to(ROOT)}"
        for page, anchor in anchored_links(ROOT / source)
        if page.is_file() and anchor not in heading_anchors(page.read_text())
    ]
    assert not broken, f"{source}: links to no heading: {broken}"


@pytest.mark.parametrize("source", readme_and_docs())
def test_files_the_readme_and_docs_name_exist(source):
    missing = sorted(p for p in named_paths((ROOT / source).read_text()) if not list(ROOT.glob(p)))
    assert not missing, f"{source} names files the repository lacks: {missing}"


def test_the_checks_find_a_missing_file_and_a_dead_anchor(tmp_path):
    page = tmp_path / "page.md"
    page.write_text(
        "# The main job: a sweep\n```\n# not a heading\n```\n## Tests\n"
        "[a](#tests) [b](#the-main-job-a-sweep) [c](#not-a-heading) [d](other.md#x) [e](https://x.org/#y)\n"
        "`config/sim/clean.toml`, `config/sim/gone.toml`, `bench/*.py`, runs/demo/run.h5, `orbitrig/+/cmd`\n"
    )
    assert heading_anchors(page.read_text()) == {"the-main-job-a-sweep", "tests"}
    assert anchored_links(page) == [
        (page, "tests"),
        (page, "the-main-job-a-sweep"),
        (page, "not-a-heading"),
        (tmp_path / "other.md", "x"),
    ]
    paths = named_paths(page.read_text())
    assert paths == {"config/sim/clean.toml", "config/sim/gone.toml", "bench/*.py"}
    assert [p for p in sorted(paths) if not list(ROOT.glob(p))] == ["config/sim/gone.toml"]
