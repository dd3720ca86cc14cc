"""How `--help` and usage errors are drawn: click's plain text, for every command group.

Typer's rich renderer (typer 0.29) imports rich's markdown, syntax highlighting and traceback
modules before it draws a line, about 190 ms of a 500 ms `orbitrig --help`; plain text carries
the same words at a start-up the bench's target allows (bench/bench_startup.py). Plain text
also pipes and greps as it reads.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import typer
import typer.core

if TYPE_CHECKING:
    from typer import _click  # typer's own copy of click (0.29)


class CommandGroup(typer.core.TyperGroup):
    """A command group whose list of commands shows each one's whole first sentence, wrapped
    to the terminal, where click would cut it to the width left beside the names ("..."); the
    sub-command it runs is noted for the error lines (orbitrig.cli.failure.entered); a sub-command
    whose --help is asked has its --sim-config help's scenario names filled in (sim_options)."""

    def resolve_command(self, ctx: _click.Context, args: list[str]):
        from orbitrig.cli.failure import entered

        name, command, rest = super().resolve_command(ctx, args)
        entered(ctx.parent is None, (command.name if command is not None else None) or name or "")
        if command is not None and set(rest) & set(ctx.help_option_names):  # its help is drawn
            from orbitrig.cli.sim_options import fill_scenarios

            fill_scenarios(command)
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


def command_group(help: str, **settings) -> typer.Typer:
    """A Typer application (the root or a sub-command group) drawn as plain text."""
    return typer.Typer(help=help, rich_markup_mode=None, cls=CommandGroup, **settings)
