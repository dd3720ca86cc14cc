"""The README and docs/ write micrometres and microseconds in prose as the CLI prints them
(rigunits.MICROMETRE 'µm', MICROSECOND 'µs'); an ASCII 'um' or 'us' is left only in literal
text: code spans and blocks (`--span-um`, `x_um`, `delay_us`)."""

from __future__ import annotations

import re

from support.paths import ROOT

from rigunits import MICROMETRE, MICROSECOND

PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
_ASCII_MICROMETRE = re.compile(r"(?<![\w-])um(?!\w)")
#: 'us' after a number or a quantity's name ('33 us', 'delay us'): the word 'us' stays free
_ASCII_MICROSECOND = re.compile(r"(?:\d|\bdelay) ?us(?!\w)")


def prose_lines(markdown: str) -> list[tuple[int, str]]:
    """(line number, text) of ``markdown`` outside fenced code blocks, with `code spans` blanked."""
    out, fenced = [], False
    for n, line in enumerate(markdown.split("\n"), 1):
        if line.lstrip().startswith("```"):
            fenced = not fenced
        elif not fenced:
            out.append((n, re.sub(r"`[^`]*`", "``", line)))
    return out


def ascii_micrometres(markdown: str) -> list[str]:
    """'LINE: text' of every prose line of ``markdown`` that writes micrometres as 'um'."""
    return [f"{n}: {line.strip()}" for n, line in prose_lines(markdown) if _ASCII_MICROMETRE.search(line)]


def ascii_microseconds(markdown: str) -> list[str]:
    """'LINE: text' of every prose line of ``markdown`` that writes microseconds as 'us'."""
    return [f"{n}: {line.strip()}" for n, line in prose_lines(markdown) if _ASCII_MICROSECOND.search(line)]


def test_the_check_finds_um_in_prose_and_leaves_literals():
    page = "a 2.4 um orbit\n`--span-um`, default 40 um,\n`x_um` (m)\n```\nspan_um = 40  # um\n```\n"
    assert ascii_micrometres(page) == ["1: a 2.4 um orbit", "2: ``, default 40 um,"]


def test_docs_write_micrometres_as_the_cli_prints_them():
    assert MICROMETRE == "\u00b5m"
    found = {str(p.relative_to(ROOT)): ascii_micrometres(p.read_text(encoding="utf-8")) for p in PAGES}
    assert {page: lines for page, lines in found.items() if lines} == {}


def test_the_check_finds_us_in_prose_and_leaves_literals_and_the_word():
    page = (
        "takes 33 us, at most\nphase deg, delay us; probe\n`delay_us` (10 µs)\ntell us, status\n```\nt_us  # us\n```\n"
    )
    assert ascii_microseconds(page) == ["1: takes 33 us, at most", "2: phase deg, delay us; probe"]


def test_docs_write_microseconds_as_the_cli_prints_them():
    assert MICROSECOND == "\u00b5s"
    found = {str(p.relative_to(ROOT)): ascii_microseconds(p.read_text(encoding="utf-8")) for p in PAGES}
    assert {page: lines for page, lines in found.items() if lines} == {}


def comment_lines(toml: str) -> list[tuple[int, str]]:
    """(line number, text) of the comments of ``toml`` (from a '#' outside a string), `code` blanked."""
    out = []
    for n, line in enumerate(toml.split("\n"), 1):
        cut = re.sub(r'"[^"]*"', lambda m: " " * len(m.group()), line).find("#")
        if cut >= 0:
            out.append((n, re.sub(r"`[^`]*`", "``", line[cut:])))
    return out


def test_the_shipped_configuration_comments_write_micro_units_as_the_cli_prints_them():
    assert comment_lines('ratios = [0.5]  # 5.76 um\nname = "a # b um"\n') == [(1, "# 5.76 um")]
    found = {
        str(p.relative_to(ROOT)): [
            f"{n}: {text}"
            for n, text in comment_lines(p.read_text(encoding="utf-8"))
            if _ASCII_MICROMETRE.search(text) or _ASCII_MICROSECOND.search(text)
        ]
        for p in sorted((ROOT / "config").rglob("*.toml"))
    }
    assert {page: lines for page, lines in found.items() if lines} == {}
