"""A command run as a background job of a terminal, as an interactive shell runs `orbitrig sweep
... &`: a pseudo-terminal (support.pseudo_terminal) made the controlling terminal of a session
whose leader, a small shell of this file (run as a script), keeps the terminal's foreground and
starts the command in a process group of its own. The kernel then applies job control to the
command for real: a read of the terminal sends it SIGTTIN, a write after `stty tostop` SIGTTOU
(either stops it unless ignored). `BackgroundJob.fg` gives it the terminal, as `fg` does."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import termios

#: the job's state letter in /proc/PID/stat: stopped by a signal (SIGTTIN, SIGTTOU, SIGTSTP)
STOPPED = "T"


class BackgroundJob:
    """``cmd`` as a background job of ``terminal`` (support.pseudo_terminal.Terminal); ``tostop``:
    the terminal set as by `stty tostop` (a background job's write stops it). ``pid``: the job's."""

    def __init__(self, terminal, cmd: list[str], *, env: dict[str, str], tostop: bool = False) -> None:
        self.terminal = terminal
        if tostop:
            attrs = termios.tcgetattr(terminal.tty)
            attrs[3] |= termios.TOSTOP
            termios.tcsetattr(terminal.tty, termios.TCSANOW, attrs)
        report, told = os.pipe()
        self.shell = subprocess.Popen(
            [sys.executable, __file__, str(told), *cmd],
            stdin=terminal.tty,
            stdout=terminal.tty,
            stderr=terminal.tty,
            start_new_session=True,
            pass_fds=(told,),
            env=env,
        )
        os.close(told)
        terminal.started()
        with os.fdopen(report) as said:
            self.pid = int(said.readline())

    def state(self) -> str:
        """The job's state letter in /proc/PID/stat ('S' sleeping, 'R' running, 'T' stopped)."""
        with open(f"/proc/{self.pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0]

    def fg(self) -> None:
        """The job brought to the terminal's foreground (the shell's `fg`, without its SIGCONT)."""
        self.shell.send_signal(signal.SIGUSR1)

    def signal(self, sig: int) -> None:
        os.kill(self.pid, sig)

    def wait(self, timeout: float) -> int:
        """The job's exit status (128 + N for signal N), once it ended (the shell ends with it)."""
        return self.shell.wait(timeout)

    def close(self) -> None:
        """The job killed if it still runs, the shell reaped."""
        if self.shell.poll() is None:
            for pid in (self.pid, self.shell.pid):
                try:
                    os.kill(pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
            self.shell.wait(10)


def _shell(told: int, cmd: list[str]) -> int:
    """The session's leader: the terminal (its standard input) made the session's, `cmd` started in a
    process group of its own (a background job), its pid said on `told`; SIGUSR1 gives it the
    terminal's foreground. Its exit status, as a shell gives it."""
    import fcntl

    fcntl.ioctl(0, termios.TIOCSCTTY, 0)  # this process's group in the terminal's foreground
    job = subprocess.Popen(cmd, process_group=0)
    signal.signal(signal.SIGUSR1, lambda *_: os.tcsetpgrp(0, job.pid))
    os.write(told, b"%d\n" % job.pid)
    os.close(told)
    code = job.wait()
    return 128 - code if code < 0 else code


if __name__ == "__main__":
    sys.exit(_shell(int(sys.argv[1]), sys.argv[2:]))
