"""How `--help` and usage errors are drawn: click's plain text, for every command group.

Typer's rich renderer (typer 0.29) imports rich's markdown, syntax highlighting and traceback
modules before it draws a line, about 190 ms of a 500 ms `orbitrig --help`; plain text carries
the same words at a start-up the bench's target allows (bench/bench_startup.py). Plain text
also pipes and greps as it reads.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import typer
import typer.core

if TYPE_CHECKING:
    from typer import _click  # typer's own copy of click (0.29)


class Command(typer.core.TyperCommand):
    """A command whose help, however it is drawn (--help, or get_help called directly), has its
    --sim-config help's scenario names filled in first (sim_options.fill_scenarios): only a drawn
    help reads the scenarios' folder."""

    def format_help(self, ctx: _click.Context, formatter: _click.HelpFormatter) -> None:
        from orbitrig.cli.sim_options import fill_scenarios

        fill_scenarios(self)
        super().format_help(ctx, formatter)


class CommandGroup(typer.core.TyperGroup):
    """A command group whose list of commands shows each one's whole first sentence, wrapped
    to the terminal, where click would cut it to the width left beside the names ("..."); the
    sub-command it runs is noted for the error lines (orbitrig.cli.failure.entered)."""

    def resolve_command(self, ctx: _click.Context, args: list[str]):
        from orbitrig.cli.failure import entered

        name, command, rest = super().resolve_command(ctx, args)
        entered(ctx.parent is None, (command.name if command is not None else None) or name or "")
        return name, command, rest

    def format_commands(self, ctx: _click.Context, formatter: _click.HelpFormatter) -> None:
        rows = []
        for name in self.list_commands(ctx):
            command = self.get_command(ctx, name)
            if command is not None and not command.hidden:
                rows.append((name, command.get_short_help_str(limit=10_000)))
        if rows:
            with formatter.section("Commands"):
                formatter.write_dl(rows)


class CommandApp(typer.Typer):
    """A Typer application whose commands are `Command`s unless one is given another class."""

    def command(self, name: str | None = None, *, cls: type[typer.core.TyperCommand] | None = None, **settings: Any):
        return super().command(name, cls=cls or Command, **settings)


def command_group(help: str, **settings) -> typer.Typer:
    """A Typer application (the root or a sub-command group) drawn as plain text."""
    return CommandApp(help=help, rich_markup_mode=None, cls=CommandGroup, **settings)
