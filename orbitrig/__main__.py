"""`orbitrig` and `python -m orbitrig`: the command line (orbitrig.cli).

Importing the command line takes about a second (every command registers); a Ctrl-C meanwhile,
before any command runs, ends the process with a line saying so (exit 130), not a traceback.
Once a command runs, its own handling applies (orbitrig.cli.signals for those that move drives).
"""

import sys


def main() -> None:
    try:
        from orbitrig.cli import main as command_line
    except KeyboardInterrupt:
        sys.stderr.write("orbitrig: interrupted (Ctrl-C) while starting; no command was run\n")
        sys.exit(130)
    command_line()


if __name__ == "__main__":
    main()
