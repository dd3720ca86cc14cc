"""`orbitrig acquire` against a board that does not send what the rig config says: frames of
another channel count or mode, bytes without the sync, a stream that stops in the middle of a
frame. Each is served by a small TCP server in a thread (a real socket, the spec's frames);
the message names what came (the header's byte offsets, the counts) and the hint where to look."""

from __future__ import annotations

import contextlib
import re
import socket
import threading
import time
from collections.abc import Iterator

import numpy as np
import pytest

from support.cli_helpers import orbitrig_here
from support.daq_encoder import SIMULTANEOUS, TRIGGER, frame, signal, slot_samples

pytestmark = pytest.mark.timeout(60)

ORBIT_HZ = 20.0


def _revolution(r: int, seq: int, mode: str, channels: int) -> bytes:
    """One revolution of the spec's frames (6 frames of 60 slots), rev number r, from frame counter seq."""
    samples = slot_samples(signal(1, channels, mode)[0], mode)
    flags = SIMULTANEOUS if mode == "simultaneous" else 0
    period_us = 1e6 / ORBIT_HZ
    return b"".join(
        frame(flags | (TRIGGER if first == 0 else 0), seq + k, r, first, samples[first : first + 60],
              int(r * period_us + first / 360 * period_us))
        for k, first in enumerate(range(0, 360, 60))
    )  # fmt: skip


@contextlib.contextmanager
def board(mode: str = "sequential", channels: int = 8, *, sync: bytes = b"", revolutions: int = 10**6,
          cut_after: int | None = None, hz: float = ORBIT_HZ, lead: bytes = b"",
          frames_at: float = 0.0) -> Iterator[str]:  # fmt: skip
    """A board on a loopback port (its socket:// URL) sending revolutions at `hz` a second; `sync`
    replaces every frame's sync bytes; `cut_after` revolutions it sends half the next one
    (ending inside a frame) and then nothing, its link left open; `lead`: bytes sent 0.3 s after
    the connection (once the acquisition began), the revolutions then `frames_at` s after it."""
    server = socket.create_server(("127.0.0.1", 0))
    stop = threading.Event()

    def serve() -> None:
        with contextlib.suppress(OSError):
            conn, _ = server.accept()
            with conn:
                t0 = time.monotonic()
                if lead:
                    stop.wait(0.3)
                    conn.sendall(lead)
                if stop.wait(max(0.0, t0 + frames_at - time.monotonic())):
                    return
                t0 = time.monotonic()
                for r in range(revolutions):
                    data = _revolution(r, 6 * r, mode, channels)
                    if sync:
                        data = data.replace(b"\xa5\x5a\x01", sync + b"\x01")
                    if r == cut_after:
                        conn.sendall(data[: len(data) // 2 + 7])
                        stop.wait()
                        return
                    conn.sendall(data)
                    if stop.wait(max(0.0, t0 + (r + 1) / hz - time.monotonic())):
                        return

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    try:
        yield f"socket://127.0.0.1:{server.getsockname()[1]}"
    finally:
        stop.set()
        server.close()
        thread.join(5)


def _acquire(url: str, *args: str) -> tuple[int, str]:
    done = orbitrig_here("acquire", "--adc", url, "--revolutions", "10", "--timeout", "1.5", *args)
    assert done.stdout == ""
    return done.returncode, done.stderr


def test_frames_of_another_channel_count_are_named_with_the_header_bytes():
    """Simultaneous frames of 6 channels where the config scans 8: was 'another A/D mode' and
    'is the orbit turning?' although 120 revolutions had come."""
    with board("simultaneous", 6) as url:
        code, err = _acquire(url, "--mode", "simultaneous")
    assert code == 2
    assert "in another A/D mode than the one configured" in err
    assert (
        "the board sends simultaneous frames with 6 samples per slot (flags bit 2 SIMULTANEOUS at byte 3, "
        "n_ch at byte 13); configured: simultaneous, 8 channels, so 8 samples per slot"
    ) in err
    assert "set [transports] adc_mode and the [[channels]] to the board's scan list" in err
    assert "is the orbit turning" not in err


@pytest.mark.parametrize(
    ("mode", "channels", "configured"), [("simultaneous", 6, "simultaneous"), ("sequential", 8, "simultaneous")]
)
def test_frames_all_of_another_mode_fail_after_a_second_not_the_timeout(mode, channels, configured):
    """Every frame of the first second of another channel count or mode: no revolution of them
    can be good, so `acquire` fails then with the same words, not after its 10 s timeout."""
    with board(mode, channels) as url:
        t0 = time.monotonic()
        done = orbitrig_here("acquire", "--adc", url, "--revolutions", "10", "--mode", configured)
        took = time.monotonic() - t0
    assert done.returncode == 2 and done.stdout == ""
    assert took < 3.0, took
    assert re.search(r"no good revolution within 1(\.\d+)? s; ", done.stderr), done.stderr
    assert "in another A/D mode than the one configured" in done.stderr
    assert f"the board sends {mode} frames with {channels if mode == 'simultaneous' else 1} sample" in done.stderr
    assert "set [transports] adc_mode and the [[channels]] to the board's scan list" in done.stderr
    assert "raise --timeout" not in done.stderr


def test_sequential_frames_where_simultaneous_is_configured():
    with board("sequential", 8) as url:
        code, err = _acquire(url, "--mode", "simultaneous")
    assert code == 2
    assert "the board sends sequential frames with 1 sample per slot" in err
    assert "configured: simultaneous, 8 channels, so 8 samples per slot" in err


def test_bytes_without_the_sync_are_not_a_stopped_orbit():
    """Every frame's sync 0xA5 0x5B: bytes come, no frame; was 'is the orbit turning?'."""
    with board(sync=b"\xa5\x5b") as url:
        code, err = _acquire(url)
    assert code == 2
    assert "frames 0 good, 0 bad" in err
    assert (
        "no valid frame in what came: each starts with the sync bytes 0xA5 0x5A (byte 0..1), version 1 "
        "(byte 2), and passes its CRC; is this the A/D board's frame stream?"
    ) in err
    assert "is [transports] adc_url (or --adc) the A/D board's frame stream" in err
    assert "is the orbit turning" not in err


def test_bytes_without_a_frame_fail_after_a_second_not_the_timeout():
    """Another device's stream on adc_url, or a serial port at another baud rate or parity: bytes
    keep coming and none makes a frame, so no revolution can come of them. `acquire` fails once
    4096 such bytes came after its first second, not after its 10 s timeout (on the rig at a
    slow orbit a block's timeout is minutes)."""
    with board(sync=b"\xa5\x5b") as url:
        t0 = time.monotonic()
        done = orbitrig_here("acquire", "--adc", url, "--revolutions", "10")
        took = time.monotonic() - t0
    assert done.returncode == 2 and done.stdout == ""
    assert took < 4.0, took  # 1 s, the CLI's start and a busy second core
    assert re.search(
        r"no good revolution within 1(\.\d+)? s; no revolution dropped; frames 0 good, 0 bad, ", done.stderr
    )
    assert "no valid frame in what came" in done.stderr and "is this the A/D board's frame stream?" in done.stderr


def test_bytes_without_a_frame_fail_once_they_are_many_not_at_the_timeout():
    """A slower stream of bytes without one frame (4200 bytes/s, a port at a lower baud rate): it
    fails once noise_bytes (12300 at 8 channels) came, about 3 s in, not at its 10 s timeout (the
    first second's look was the only one before the timeout)."""
    with board(sync=b"\xa5\x5b", hz=5.0) as url:
        t0 = time.monotonic()
        done = orbitrig_here("acquire", "--adc", url, "--revolutions", "10")
        took = time.monotonic() - t0
    assert done.returncode == 2 and done.stdout == ""
    waited = re.search(r"no good revolution within ([\d.]+) s; no revolution dropped; frames 0 good", done.stderr)
    assert waited and 2.5 <= float(waited[1]) < 8.0, done.stderr  # 12300 bytes at 4200 a second: 2.9 s
    assert took < 9.0, took
    assert "is this the A/D board's frame stream?" in done.stderr


def test_the_rest_of_a_large_frame_then_a_slow_orbit_is_no_noise():
    """The link opened in the middle of a board's largest frame (4099 of 4100 bytes: 255 slots of 8
    channels) and the orbit slow, its first whole frame 1.3 s later: a legitimate start, not
    another device's stream; it was failed at the first second (4096 bytes without a frame)."""
    with board(lead=bytes(range(256)) * 16 + b"\x00\x01\x02", frames_at=1.3, revolutions=400) as url:
        done = orbitrig_here("acquire", "--adc", url, "--revolutions", "10")
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("10 revolutions averaged, 0 dropped, frames bad 0, bytes skipped 4099, "), done.stdout


def test_a_stream_stopped_inside_a_frame_is_said_so():
    """Two good revolutions, then half the third (7 bytes into its fourth frame) and silence on
    an open link: was 'only 1 of 10 good revolutions ... is the orbit speed steady?'."""
    with board(cut_after=2) as url:
        code, err = _acquire(url)
    assert code == 2
    assert re.search(r"only [12] of 10 good revolutions within 1.5 s", err)
    assert "then the stream stopped, in the middle of a frame (7 bytes of it came)" in err
    assert "has sent nothing for" in err and "its link is open" in err
    assert "is the orbit turning?" in err and "is the orbit speed steady" not in err


def test_the_good_stream_of_the_same_server_is_averaged():
    """The server's frames are the spec's: the faults above are the faults, not the server."""
    with board(revolutions=12) as url:
        done = orbitrig_here("acquire", "--adc", url, "--revolutions", "10", "--timeout", "5", "--counts")
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("10 revolutions averaged, 0 dropped")
    assert np.isfinite(float(done.stdout.splitlines()[2].split()[3]))
