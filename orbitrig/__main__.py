"""`orbitrig` and `python -m orbitrig`: the command line (orbitrig.cli).

Importing the command line takes about a second (every command registers); a Ctrl-C meanwhile,
before any command runs, ends the process with a line saying so (exit 130), not a traceback.
SIGQUIT (Ctrl-\\) is handled from the first line of `main` on, as SIGTERM is by default before a
command handles signals: it ends the process at once, with a line saying so and exit 131
(128 + 3, as 143 for SIGTERM), not Python's default core dump; so it does in a command that handles
no SIGQUIT of its own (`orbitrig sim`, `orbitrig dashboard`). A SIGQUIT the process was started
with ignored stays ignored (orbitrig.cli.signals.IGNORED_AT_START reads it so). Only the
interpreter's own start-up, before `main` runs, is left to the default.
Once a command runs, its own handling applies (orbitrig.cli.signals for those that move drives).
"""

import os
import signal
import sys

#: exit status of a SIGQUIT before the command handles it: 128 + its number, as a shell reports a
#: process that signal ended (SIGTERM: 143)
QUIT_STATUS = 128 + signal.SIGQUIT

_loading = True  # the command line is being imported: no command has run


def _quit(_sig: int, _frame: object) -> None:
    """SIGQUIT a command does not handle (before it handles signals, or one that handles none): end
    at once, as SIGTERM does by default, with a line saying so and no core."""
    said = " while starting; no command was run" if _loading else "; ended at once"
    os.write(2, f"orbitrig: SIGQUIT{said} (no core dump)\n".encode())
    os._exit(QUIT_STATUS)


def quit_handled() -> None:
    """Handle SIGQUIT as above (`_quit`), unless the process was started with it ignored."""
    if signal.getsignal(signal.SIGQUIT) is signal.SIG_DFL:
        signal.signal(signal.SIGQUIT, _quit)


def main() -> None:
    global _loading
    quit_handled()
    try:
        from orbitrig.cli import main as command_line
    except KeyboardInterrupt:
        sys.stderr.write("orbitrig: interrupted (Ctrl-C) while starting; no command was run\n")
        sys.exit(130)
    _loading = False
    command_line()


if __name__ == "__main__":
    main()
