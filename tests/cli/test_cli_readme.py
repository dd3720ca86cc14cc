"""Every command in the README's shell blocks runs: the ones that need no rig run for real
(against the simulator, run directories in a temporary folder); every other `orbitrig`
command is held to its command's --help (the command exists, every option it uses exists);
other programs exist on this machine, scripts and files exist. The `orbitrig` commands the pages
of docs/, CONTRIBUTING.md and the lab's broker notes show (fenced or indented blocks) are held
to --help the same way."""

from __future__ import annotations

import functools
import re
import shlex
import shutil
from pathlib import Path

import pytest
from support.cli_helpers import orbitrig, orbitrig_here
from support.paths import ROOT


README = ROOT / "README.md"

#: README command -> exit status here (no rig attached). Each must appear in the README as written.
RUN_HERE = {
    "orbitrig sweep --sim --out runs/demo": 0,
    "orbitrig report runs/demo": 0,
    "orbitrig reduce runs/demo --model kc7 --freq-dep power:auto": 0,
    "orbitrig sweep --sim --dry-run --matrix paper": 0,
    "orbitrig sweep --matrix paper --out runs/paper": 2,  # on the rig: here it says there is no rig
    "orbitrig calibrate list": 0,
    "orbitrig calibrate show": 0,
    "orbitrig design --model kcd11 --spin 1000 --match": 0,
    "orbitrig design --model kc8 --spin 1000 --matrix demo --target 0.2 --json": 0,
    "orbitrig design --model kc8 --spin 1000 --noise-from runs/demo/run.h5": 0,  # a run file: the main job's
}


def readme_commands(page: Path = README) -> list[str]:
    """Commands of the untagged or shell fenced blocks of ``page`` (the README), each once:
    continuation lines (a trailing backslash, or a synopsis line that starts with an option)
    joined, comments dropped, `a && b` split."""
    lines, block, lang = [], None, ""
    for line in page.read_text().splitlines():
        fence = re.match(r"\s*```(\w*)", line)
        if fence:
            block, lang = (None, "") if block is not None else ([], fence.group(1))
            continue
        if block is None or lang not in ("", "sh", "bash", "shell", "console"):
            continue
        text = re.sub(r"\s+#.*$", "", line).strip()
        if lines and (lines[-1].endswith("\\") or text.startswith(("[", "-"))):
            lines[-1] = lines[-1].rstrip("\\").strip() + " " + text
        elif text:
            lines.append(text)
    commands = [c.strip() for line in lines for c in line.split("&&")]
    return list(dict.fromkeys(c for c in commands if c))


@functools.cache
def help_text(*path: str) -> str:
    """`orbitrig PATH... --help` in this process (typer's runner): the same text, no interpreter started."""
    res = orbitrig_here(*path, "--help")
    assert res.returncode == 0, f"orbitrig {' '.join(path)} --help: {res.stderr}"
    return res.stdout


def command_path(words: list[str]) -> list[str]:
    """The sub-command words of `orbitrig WORDS...` (a group such as `drives` takes one more)."""
    path = []
    for w in words:
        if w.startswith("-") or not re.fullmatch(r"[a-z][a-z-]*", w):
            break
        path.append(w)
        if "Commands" not in help_text(*path):
            break
    return path


def check_orbitrig_command(words: list[str]) -> None:
    path = command_path(words)
    text = help_text(*path)
    options = {o for w in words for o in re.findall(r"--[a-z][a-z0-9-]*", w)}
    unknown = [o for o in sorted(options) if not re.search(rf"(?<![\w-]){re.escape(o)}(?![\w-])", text)]
    assert not unknown, f"orbitrig {' '.join(path)}: no option {', '.join(unknown)}"


def test_readme_has_commands_and_the_ones_run_here():
    commands = readme_commands()
    assert len(commands) >= 15
    for command in RUN_HERE:
        assert command in commands, f"README no longer shows {command!r}: update RUN_HERE"
    assert "tools/run-tests" in commands


@pytest.mark.parametrize("command", readme_commands())
def test_readme_command_exists_with_its_options(command):
    words = shlex.split(command.replace("~", "HOME"))
    if words[0] == "orbitrig":
        check_orbitrig_command(words[1:])
    elif words[0] == "python3" and words[1:3] == ["-m", "pip"]:
        assert (ROOT / "pyproject.toml").is_file()
        if ".[test]" in words:
            assert "[project.optional-dependencies]\ntest" in (ROOT / "pyproject.toml").read_text()
    elif words[0] == "python3" and words[1] == "-m" and words[2].startswith("bench."):
        assert (ROOT / "bench" / f"{words[2].removeprefix('bench.')}.py").is_file(), words[2]  # run from the root
    elif words[0] == "python3" and words[1] == "-m":
        assert words[2] in ("pytest", "venv", "orbitrig")
    elif words[0] == "python3":
        assert (ROOT / words[1]).is_file(), words[1]
    elif words[0] == ".":  # the shell's source: a virtual environment the README makes first
        venv = words[1].removesuffix("/bin/activate")
        assert f"python3 -m venv {venv}" in readme_commands(), words[1]
    elif words[0] == "export":  # an environment variable orbitrig reads
        name = words[1].split("=", 1)[0]
        assert any(name in f.read_text() for f in (ROOT / "orbitrig" / "config").glob("*.py")), name
    elif "/" in words[0]:
        assert (ROOT / words[0]).is_file(), words[0]
    else:
        assert shutil.which(words[0]), f"{words[0]} is not installed (tools/run-tests installs the test tools)"


#: pages besides the README that show an operator or analyst `orbitrig` commands
DOC_PAGES = sorted(ROOT.glob("docs/**/*.md")) + [ROOT / "CONTRIBUTING.md", ROOT / "config" / "mosquitto" / "README.md"]


def indented_commands(page: Path) -> list[str]:
    """Commands of ``page``'s indented (4-space) code blocks, as `readme_commands` joins them."""
    lines: list[str] = []
    for line in page.read_text().splitlines():
        text = re.sub(r"\s+#.*$", "", line).strip() if line.startswith("    ") else ""
        if lines and lines[-1].endswith("\\"):
            lines[-1] = lines[-1].rstrip("\\").strip() + " " + text
        elif text and not text.startswith(("-", "*")):  # an item of a nested list is no command
            lines.append(text)
    return lines


def doc_orbitrig_commands() -> list[tuple[str, str]]:
    """(page, command) of every `orbitrig` command (or `python3 -m orbitrig`, an environment
    variable set before it) the pages of DOC_PAGES show in their code blocks, each once."""
    found = {}
    for page in DOC_PAGES:
        for command in readme_commands(page) + indented_commands(page):
            command = re.sub(r"^([A-Z_]+=\S+\s+)+", "", command).replace("python3 -m orbitrig ", "orbitrig ")
            command = re.split(r"\s{3,}", command)[0]  # a synopsis line's description after it
            if command.startswith("orbitrig "):
                found.setdefault(command, str(page.relative_to(ROOT)))
    return [(page, command) for command, page in found.items()]


def test_docs_show_orbitrig_commands():
    pages = {page for page, _ in doc_orbitrig_commands()}
    for page in ("docs/catalog.md", "docs/calibration.md", "docs/orbit-table.md", "config/mosquitto/README.md"):
        assert page in pages, f"{page} shows no orbitrig command any more: update the pages checked"


@pytest.mark.parametrize(("page", "command"), doc_orbitrig_commands())
def test_docs_command_exists_with_its_options(page, command):
    check_orbitrig_command(shlex.split(command.replace("~", "HOME"))[1:])


def test_the_option_check_finds_an_option_a_command_lacks():
    with pytest.raises(AssertionError, match="no option --sim-confg"):
        check_orbitrig_command(["sweep", "--sim", "--sim-confg", "clean", "--out", "runs/x"])


def test_readme_commands_that_need_no_rig_run(tmp_path):
    """In README order: the main job on the simulator, its report and re-identification,
    the paper's plan, the sweep on the rig (no rig here: exit 2, no run directory), the
    calibration history and the design of orbit frequencies, with the rig times the README gives."""
    runs, said = tmp_path / "runs", {}
    for command in [c for c in readme_commands() if c in RUN_HERE]:
        args = [str(runs / w.removeprefix("runs/")) if w.startswith("runs/") else w for w in shlex.split(command)]
        p = said[command] = orbitrig(*args[1:], timeout=600)
        assert p.returncode == RUN_HERE[command], f"{command}: {p.stdout[-2000:]}\n{p.stderr[-2000:]}"
    assert (runs / "demo" / "run.h5").is_file() and (runs / "demo" / "coefficients.csv").is_file()
    assert list((runs / "demo" / "plots").glob("*.png"))
    assert not (runs / "paper").exists()
    # "--match takes 115 s against the paper list's 163 s" (README, design)
    match = said["orbitrig design --model kcd11 --spin 1000 --match"].stdout
    assert re.search(r"^candidate: 10 ratios x both, 50 revolutions, rig time 2:43,", match, re.M), match
    assert re.search(r"^proposal : 6 ratios x both, .* rig time 1:55,", match, re.M | re.S), match
    noise = said["orbitrig design --model kc8 --spin 1000 --noise-from runs/demo/run.h5"].stdout
    assert re.search(r"^noise measured: run\s+\S+/run\.h5\s+\(piezo, u_\*", noise, re.M), noise


def readme_synopsis() -> list[str]:
    """The command lines of the README's synopsis: the first fenced block under "## Command line"."""
    text = README.read_text()
    section = text[text.index("\n## Command line\n") :]
    block = section.split("```", 2)[1]
    return [line.strip() for line in block.splitlines() if line.strip().startswith("orbitrig ")]


def cli_commands() -> list[str]:
    """Every command of the `orbitrig` CLI as typed, a group's as `group sub` (`drives run`)."""
    import typer

    from orbitrig.cli import app

    def listed(group) -> list[str]:
        return group.list_commands(None)  # a TyperGroup lists its commands in their help order

    root = typer.main.get_command(app)
    names = []
    for name in listed(root):
        sub = root.get_command(None, name)  # type: ignore[attr-defined]
        names += [f"{name} {s}" for s in listed(sub)] if isinstance(sub, typer.core.TyperGroup) else [name]
    return names


def test_every_command_of_the_cli_has_its_line_in_the_readme_synopsis():
    synopsis = readme_synopsis()
    commands = cli_commands()
    assert {"version", "sim", "drives run", "calibrate probes", "catalog export"} <= set(commands)
    missing = [c for c in commands if not any(re.match(rf"orbitrig {c}(?![\w-])", line) for line in synopsis)]
    assert not missing, f"README's synopsis has no line for: {', '.join(missing)}"
    shown = {" ".join(command_path(shlex.split(line)[1:])) for line in synopsis}
    assert shown <= set(commands), shown - set(commands)
