"""A terminal for a command run as a process: a pseudo-terminal whose other end the test reads
(``screen``) and types on (``press``), through the terminal's real line discipline: Ctrl-S (XOFF)
stops the command's output there, as an operator's Ctrl-S does, until Ctrl-Q (XON)."""

from __future__ import annotations

import os
import pty
import threading
import time

CTRL_S, CTRL_Q = b"\x13", b"\x11"  # XOFF, XON


class Terminal:
    """``tty``: the file descriptor the command writes on (its standard error, say); closed here
    once the command has it (``started``)."""

    def __init__(self) -> None:
        self.master, self.tty = pty.openpty()
        self.screen = bytearray()
        threading.Thread(target=self._read, daemon=True).start()

    def started(self) -> None:
        """The command holds the terminal: this process's copy of its end is closed."""
        os.close(self.tty)

    def press(self, keys: bytes) -> None:
        os.write(self.master, keys)

    def shows(self, text: str, timeout: float) -> None:
        """Wait until ``text`` has been written on the terminal (fail after ``timeout`` s)."""
        deadline = time.monotonic() + timeout
        while text.encode() not in self.screen:
            assert time.monotonic() < deadline, f"not on the terminal: {text!r}\n{self.text()[-2000:]}"
            time.sleep(0.05)

    def text(self) -> str:
        return self.screen.decode(errors="replace")

    def close(self) -> None:
        os.close(self.master)

    def _read(self) -> None:
        try:
            while data := os.read(self.master, 65536):
                self.screen.extend(data)
        except OSError:  # the command, the terminal's last writer, has gone
            pass
