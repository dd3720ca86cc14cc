"""The one wording of every command's failure on standard error, and its exit.

Each command says what failed as

    orbitrig COMMAND: error: MESSAGE
    orbitrig COMMAND: error (PART): MESSAGE     # PART: which part failed (config, link, limit, ...)

COMMAND is the sub-command running (`sweep`, `drives status`, `catalog add`), as the command
groups resolved it (orbitrig.cli.help_text.CommandGroup), so no command repeats its own name;
a thread or a helper shared by commands may name it (``command``). The exit status is the
README's: 1 failed, 2 bad configuration or usage (3 stopped and 4 aborted are a run's outcomes,
not errors). Notes and warnings are not errors and keep their own words.
"""

from __future__ import annotations

from typing import NoReturn

import typer

EXIT_FAILED = 1
EXIT_USAGE = 2


#: the sub-command running, word by word as its groups resolved it (CommandGroup.resolve_command)
_RUNNING: list[str] = []


def entered(root: bool, name: str) -> None:
    """A command group (``root``: the `orbitrig` group itself) resolved its sub-command ``name``."""
    if root:
        _RUNNING.clear()
    _RUNNING.append(name)


def command_name() -> str:
    """The sub-command running (`drives status`); "" before one is resolved."""
    return " ".join(_RUNNING)


def error_line(message: str, part: str | None = None, command: str | None = None) -> str:
    """'orbitrig COMMAND: error: MESSAGE' ('error (PART)' with a part); ``command`` None: the one running."""
    name = command_name() if command is None else command
    head = f"orbitrig {name}" if name else "orbitrig"
    return f"{head}: error{f' ({part})' if part else ''}: {message}"


def say_error(message: str, part: str | None = None, command: str | None = None) -> None:
    """error_line on standard error (a reader gone away does not fail the command: terminal.say)."""
    from orbitrig.cli.terminal import say

    say(error_line(message, part, command), err=True)


def fail(message: str, code: int = EXIT_USAGE, part: str | None = None, command: str | None = None) -> NoReturn:
    """say_error, then exit ``code`` (default 2: bad configuration or usage); a message standard
    error cannot take keeps ``code`` (the boundary reads it from the Exit being raised:
    orbitrig.cli.boundary)."""
    try:
        raise typer.Exit(code)
    except typer.Exit:
        say_error(message, part, command)
        raise
