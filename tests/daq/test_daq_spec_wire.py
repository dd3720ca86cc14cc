"""The readers held byte for byte to the specs (docs/protocols: adc-frames.md, can-node.md): golden
frames written out by hand from the spec tables, field by field at their offsets."""

from __future__ import annotations

import asyncio
import itertools
import os
import struct
import termios

import can
import numpy as np
import pytest

from daq.adc import AdcReader
from daq.aux import AuxSensors
from daq.frames import FrameDecoder
from daq.revolutions import RevolutionAssembler
from daq.transport import open_link
from sim.config import NoiseConfig, SimConfig
from support.spec_crc import crc16_ccitt_false
from sim.rig import SimRig

pytestmark = pytest.mark.timeout(30)


def body(
    flags: int,
    seq: int,
    rev: int,
    first_slot: int,
    n_slots: int,
    n_ch: int,
    t_us: int,
    samples: list[int],
    version: int = 1,
) -> bytes:
    """version .. last sample byte, from the spec's offset table (little-endian)."""
    b = bytes([version, flags]) + seq.to_bytes(2, "little") + rev.to_bytes(4, "little")
    b += first_slot.to_bytes(2, "little") + bytes([n_slots, n_ch]) + t_us.to_bytes(4, "little")
    return b + b"".join(int(s).to_bytes(2, "little", signed=True) for s in samples)


def golden(*args, **kw) -> bytes:
    b = body(*args, **kw)
    return b"\xa5\x5a" + b + crc16_ccitt_false(b).to_bytes(2, "little")


def test_crc_reference_is_the_catalogue_check_value():
    assert crc16_ccitt_false(b"123456789") == 0x29B1


def test_golden_frame_decodes_field_by_field():
    wire = golden(0x05, 0x1234, 0x89ABCDEF, 0, 2, 2, 0xFEDCBA98, [1, -2, 0x1234, -32768])
    (f,) = FrameDecoder().feed(wire)
    assert (f.flags, f.seq, f.rev, f.first_slot, f.n_slots, f.n_ch, f.t_us) == (
        0x05,
        0x1234,
        0x89ABCDEF,
        0,
        2,
        2,
        0xFEDCBA98,
    )
    assert f.trigger and f.simultaneous and not f.overrun
    np.testing.assert_array_equal(f.samples, [[1, -2], [0x1234, -32768]])  # slot-major


def bad_crc_variants() -> dict[str, bytes]:
    b = body(0x01, 7, 3, 0, 45, 1, 1000, list(range(45)))
    return {
        "crc over sync too": b"\xa5\x5a" + b + crc16_ccitt_false(b"\xa5\x5a" + b).to_bytes(2, "little"),
        "crc big-endian": b"\xa5\x5a" + b + crc16_ccitt_false(b).to_bytes(2, "big"),
        "crc over samples only": b"\xa5\x5a" + b + crc16_ccitt_false(b[16:]).to_bytes(2, "little"),
    }


@pytest.mark.parametrize("name", sorted(bad_crc_variants()))
def test_crc_coverage_and_byte_order_are_the_specs(name):
    dec = FrameDecoder()
    assert dec.feed(bad_crc_variants()[name]) == [] and dec.frame_errors == {"crc": 1}


HEADER_ERRORS = {
    **{f"reserved flag bit {bit}": (1 << bit, 0, 45, 1) for bit in range(3, 8)},
    "TRIGGER away from slot 0": (0x01, 45, 45, 1),
    "n_slots 0": (0x00, 45, 0, 1),
    "n_ch 0 (simultaneous)": (0x04, 45, 45, 0),
    "sequential with 2 samples per slot": (0x00, 45, 45, 2),
    "first_slot + n_slots = 361": (0x00, 359, 2, 1),
    "first_slot 360": (0x00, 360, 1, 1),
}


@pytest.mark.parametrize("name", sorted(HEADER_ERRORS))
def test_header_fields_outside_the_spec_are_rejected(name):
    flags, fs, ns, nch = HEADER_ERRORS[name]
    dec = FrameDecoder()
    assert dec.feed(golden(flags, 0, 0, fs, ns, nch, 0, [0] * (ns * nch))) == []
    assert dec.frame_errors == {"header": 1}


def test_header_limits_inside_the_spec_are_accepted():
    frames = [
        golden(0x02, 1, 0, 359, 1, 1, 0, [5]),  # last slot alone, OVERRUN
        golden(0x05, 2, 0, 0, 255, 1, 0, [0] * 255),  # 255 slots, simultaneous C=1
        golden(0x04, 3, 0, 0, 1, 255, 0, list(range(255))),
    ]  # n_ch 255
    dec = FrameDecoder()
    got = dec.feed(b"".join(frames))
    assert [(f.first_slot, f.n_slots, f.n_ch) for f in got] == [(359, 1, 1), (0, 255, 1), (0, 1, 255)]
    assert dec.frames_bad == 0


@pytest.mark.parametrize("channels", [1, 2, 8, 45, 180, 360])
def test_sequential_scan_of_any_divisor_of_360(channels):
    """C must divide 360 (and nothing else): channel k at slots k, k + C, ..."""
    asm = RevolutionAssembler(channels, "sequential")
    assert asm.slots.shape == (channels, 360 // channels)
    np.testing.assert_array_equal(asm.slots[-1], np.arange(channels - 1, 360, channels))
    samples = np.arange(360)
    wire = b"".join(
        golden(0x01 if fs == 0 else 0, i, 9, fs, 90, 1, 1000 * i, samples[fs : fs + 90])
        for i, fs in enumerate(range(0, 360, 90))
    )
    wire += golden(0x01, 4, 10, 0, 90, 1, 4000, samples[:90])
    revs = asm.push_batch(FrameDecoder().feed_batch(wire)).revolutions()
    assert len(revs) == 1 and revs[0].period_s == pytest.approx(4000e-6)
    np.testing.assert_array_equal(revs[0].counts, asm.slots)  # sample value = its slot


@pytest.mark.parametrize(
    "channels,mode",
    [(7, "sequential"), (0, "sequential"), (720, "sequential"), (256, "simultaneous"), (0, "simultaneous")],
)
def test_scan_sizes_outside_the_spec_are_refused(channels, mode):
    with pytest.raises(ValueError, match=f"channels={channels}"):
        RevolutionAssembler(channels, mode)


_names = itertools.count()


class FakeClock:
    def __init__(self):
        self.t = 50.0

    def __call__(self):
        return self.t


async def test_aux_lengths_and_unsigned_fields_are_the_specs():
    """uint16 fields above 32767 stay positive; a frame whose length is not the
    spec's (8, 8, 4, 1 bytes) is counted as malformed and never read."""
    channel = f"daq-aux-spec-{next(_names)}"
    tx = can.Bus(interface="virtual", channel=channel)
    try:
        async with AuxSensors(channel, interface="virtual", clock=FakeClock()) as aux:

            def send(can_id, data):
                tx.send(can.Message(arbitration_id=can_id, data=data, is_extended_id=False))

            send(0x181, struct.pack("<hhhH", -27315, 32767, -1, 0xFFFF))
            send(0x281, struct.pack("<HHHH", 0xFFFF, 0x8000, 40000, 1))
            send(0x381, struct.pack("<HH", 65000, 0x0002))
            send(0x701, b"\x05")
            send(0x381, struct.pack("<HHHH", 1, 0x0001, 0, 0))  # 8 bytes: not the spec's layout
            send(0x181, bytes(4))  # too short
            send(0x701, b"\x05\x00")  # heartbeat is 1 byte
            for _ in range(200):
                if aux.frames_received + aux.frames_malformed >= 7:
                    break
                await asyncio.sleep(0.01)
            s = aux.latest()
            assert (aux.frames_received, aux.frames_malformed) == (4, 3)
            assert s.t_recess == pytest.approx(0.0, abs=1e-9) and s.t_groove == pytest.approx(327.67 + 273.15)
            assert s.t_supply == pytest.approx(-0.01 + 273.15)
            assert s.flow == pytest.approx(655.35e-3 / 60)
            assert s.p_supply == 65_535e3 and s.p_recess == (32_768e3, 40_000e3, 1e3, 65_000e3)
            assert s.pump_off and not s.sensor_fault  # the 8-byte 0x381 was not read
            assert s.beta == pytest.approx((32_768 + 40_000 + 1 + 65_000) / 4 / 65_535)
            assert s.operational
    finally:
        tx.shutdown()


async def test_serial_link_has_no_flow_control():
    """docs/protocols/adc-frames.md, the byte stream: a serial port, any baud rate, no flow control."""
    master, slave = os.openpty()
    path = os.ttyname(slave)
    try:
        link = await open_link(f"{path}?baud=921600", lambda data: None, lambda err: None)
        try:
            iflag, _, cflag, _, _, _, cc = termios.tcgetattr(link._fd)
            assert not iflag & (termios.IXON | termios.IXOFF | termios.IXANY)
            assert not cflag & termios.CRTSCTS
            assert cc[termios.VMIN] == 1
        finally:
            link.close()
    finally:
        os.close(master)
        os.close(slave)


@pytest.mark.parametrize("direction", [1, -1], ids=["forward", "backward"])
async def test_whirl_direction_shows_in_the_phasors_not_in_the_slot_order(direction):
    """Sequential scan, noise off: every channel's phasor (fitted at its own slots
    k, k + 8, ...) is the simulator's truth to the ADC resolution in both
    directions; y lags x by 90 degrees forward and leads it backward."""
    cfg = SimConfig()
    cfg.noise = NoiseConfig(enabled=False)
    spin, orbit = 2 * np.pi * 30.0, direction * 2 * np.pi * 12.5
    async with SimRig(cfg, speedup=20.0, can_channel=None, adc_pty=False) as rig:
        rig.local_control(spin=spin, orbit=orbit)
        async with AdcReader(
            rig.adc_url, channels=8, mode="sequential", gains=cfg.adc.gains, offsets=cfg.adc.offsets
        ) as adc:
            block = await adc.acquire(4, timeout=20)
        truth = rig.true_phasors(spin, orbit)
    names = list(cfg.adc.channels)
    for k, name in enumerate(names):
        assert abs(block.phasors[k] - truth[name]) <= 0.25 * cfg.adc.gains[k], name
    x, y = block.phasors[names.index("x_a")], block.phasors[names.index("y_a")]
    assert np.degrees(np.angle(y / x)) == pytest.approx(-90.0 * direction, abs=3.0)
    assert block.orbit_speed == pytest.approx(abs(orbit), rel=1e-3)
