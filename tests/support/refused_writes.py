"""A process whose writes on one descriptor the kernel refuses with an errno of the test's choice
(a seccomp filter on write(2)): the fault of a quota that refuses standard output's file (EDQUOT),
which the test's file systems cannot give (the root user is above every quota, and tmpfs here has
none). The filter is the process's own, set in `subprocess`'s ``preexec_fn``, and kept across exec."""

from __future__ import annotations

import ctypes
import platform
import struct
from collections.abc import Callable

#: write(2)'s number per machine (the filter compares the system call's number)
_WRITE = {"x86_64": 1, "aarch64": 64}
_PR_SET_NO_NEW_PRIVS, _PR_SET_SECCOMP, _SECCOMP_MODE_FILTER = 38, 22, 2
_SECCOMP_RET_ALLOW, _SECCOMP_RET_ERRNO = 0x7FFF0000, 0x00050000
_LD_W_ABS, _JEQ_K, _RET_K = 0x20, 0x15, 0x06  # BPF_LD|BPF_W|BPF_ABS, BPF_JMP|BPF_JEQ|BPF_K, BPF_RET|BPF_K


class _Program(ctypes.Structure):
    _fields_ = [("len", ctypes.c_ushort), ("filter", ctypes.c_void_p)]


def writes_refused(fd: int, code: int) -> Callable[[], None]:
    """A ``preexec_fn`` after which every write(2) on descriptor ``fd`` fails with errno ``code``
    (the descriptor's low 32 bits compared: seccomp_data.args[0], little-endian)."""
    nr = _WRITE[platform.machine()]
    steps = [
        (_LD_W_ABS, 0, 0, 0),  # seccomp_data.nr
        (_JEQ_K, 0, 3, nr),  # not write(2): allow
        (_LD_W_ABS, 0, 0, 16),  # seccomp_data.args[0], its low word
        (_JEQ_K, 0, 1, fd),  # another descriptor: allow
        (_RET_K, 0, 0, _SECCOMP_RET_ERRNO | code),
        (_RET_K, 0, 0, _SECCOMP_RET_ALLOW),
    ]
    code_bytes = b"".join(struct.pack("HBBI", *step) for step in steps)

    def refuse() -> None:
        buffer = ctypes.create_string_buffer(code_bytes, len(code_bytes))
        program = _Program(len(steps), ctypes.cast(buffer, ctypes.c_void_p))
        libc = ctypes.CDLL(None, use_errno=True)
        if libc.prctl(_PR_SET_NO_NEW_PRIVS, 1, 0, 0, 0) or libc.prctl(
            _PR_SET_SECCOMP, _SECCOMP_MODE_FILTER, ctypes.byref(program), 0, 0
        ):
            raise OSError(ctypes.get_errno(), "seccomp filter refused")

    return refuse
