"""The simulator's wire formats held byte for byte to the specs (docs/protocols: adc-frames.md,
can-node.md): golden frames written out by hand from the spec tables, field by
field at their offsets, never with the simulator's own struct layouts."""

from __future__ import annotations

import numpy as np
import pytest

from sim.adc_board import AdcBoard
from sim.can_node import encode_aux
from sim.config import CHANNEL_GAINS, CHANNEL_NAMES, AdcConfig, SimConfig
from support.spec_crc import crc16_ccitt_false


def golden(
    flags: int, seq: int, rev: int, first_slot: int, n_slots: int, n_ch: int, t_us: int, samples: list[int]
) -> bytes:
    """One frame, assembled from the spec's offset table (little-endian)."""
    body = bytearray()
    body += bytes([1])  # 2 version
    body += bytes([flags])  # 3 flags
    body += seq.to_bytes(2, "little")  # 4 seq u16
    body += rev.to_bytes(4, "little")  # 6 rev u32
    body += first_slot.to_bytes(2, "little")  # 10 first_slot u16
    body += bytes([n_slots, n_ch])  # 12 n_slots u8, 13 n_ch u8
    body += t_us.to_bytes(4, "little")  # 14 t_us u32
    assert len(body) == 16
    for s in samples:  # 18 int16, slot-major
        body += int(s).to_bytes(2, "little", signed=True)
    # CRC over version .. last sample byte, appended little-endian
    return b"\xa5\x5a" + bytes(body) + crc16_ccitt_false(bytes(body)).to_bytes(2, "little")


def test_simultaneous_trigger_frame_is_the_golden_frame():
    board = AdcBoard(channels=2, mode="simultaneous", frame_slots=2)
    board.seq, board.rev = 0x1234, 0x89ABCDEE  # the trigger makes rev 0x89ABCDEF
    counts = np.array([[1, -2], [0x1234, -32768]], np.int16)
    t = np.array([(0xFEDCBA98 + 0.5) * 1e-6, (0xFEDCBA98 + 100.5) * 1e-6])
    wire = board.encode(360 * 7, counts, t)
    want = golden(0x05, 0x1234, 0x89ABCDEF, 0, 2, 2, 0xFEDCBA98, [1, -2, 0x1234, -32768])
    assert wire == want
    assert wire[18:26] == bytes.fromhex("0100feff34120080")  # slot-major int16 LE


def test_sequential_frames_one_sample_per_slot_and_wraps():
    """Sequential: n_ch = 1, flags without bit 2; seq wraps 65535 -> 0, rev and t_us wrap (u32)."""
    board = AdcBoard(channels=8, mode="sequential", frame_slots=180)
    board.seq, board.rev = 0xFFFF, 0xFFFFFFFF
    counts = np.arange(360, dtype=np.int16)
    t0 = 2**32 - 1000  # us: the board clock wraps inside this revolution
    t = (t0 + 0.5 + 100.0 * np.arange(360)) * 1e-6
    wire = board.encode(360 * 3, counts, t)
    size = 18 + 2 * 180 + 2
    assert len(wire) == 2 * size
    assert wire[:size] == golden(0x01, 0xFFFF, 0, 0, 180, 1, t0, list(range(180)))
    t1 = (t0 + 18000) & 0xFFFFFFFF
    assert wire[size:] == golden(0x00, 0x0000, 0, 180, 180, 1, t1, list(range(180, 360)))


@pytest.mark.parametrize("frame_slots", [1, 7, 45, 100, 255])
@pytest.mark.parametrize("g0", [0, 1, 359, 360 * 5 + 137])
def test_frames_never_span_two_revolutions(frame_slots, g0):
    board = AdcBoard(channels=8, mode="sequential", frame_slots=frame_slots)
    n = 800
    wire = board.encode(g0, np.zeros(n, np.int16), np.arange(n) * 1e-4)
    pos, slot, seen = 0, g0, 0
    while pos < len(wire):
        assert wire[pos : pos + 2] == b"\xa5\x5a"
        flags = wire[pos + 3]
        first_slot = int.from_bytes(wire[pos + 10 : pos + 12], "little")
        n_slots, n_ch = wire[pos + 12], wire[pos + 13]
        assert flags & 0xF8 == 0  # bits 3..7 zero
        assert first_slot == slot % 360 and 1 <= n_slots <= 255 and n_ch == 1
        assert first_slot + n_slots <= 360
        assert bool(flags & 0x01) == (first_slot == 0)
        slot += n_slots
        seen += n_slots
        pos += 18 + 2 * n_slots + 2
    assert seen == n and pos == len(wire)


def test_lost_frames_advance_seq_and_flag_overrun_on_the_next():
    board = AdcBoard(channels=8, mode="sequential", frame_slots=90)
    board.drop = 1
    wire = board.encode(0, np.zeros(360, np.int16), np.arange(360) * 1e-4)
    size = 18 + 180 + 2
    frames = [wire[i : i + size] for i in range(0, len(wire), size)]
    assert len(frames) == 3  # the trigger frame was lost in the FIFO
    assert [int.from_bytes(f[4:6], "little") for f in frames] == [1, 2, 3]
    assert [f[3] for f in frames] == [0x02, 0x00, 0x00]  # OVERRUN on the first frame after the loss
    assert all(int.from_bytes(f[6:10], "little") == 1 for f in frames)  # the trigger still counted


def test_aux_frames_are_the_golden_payloads():
    """0x181 int16 0.01 degC x3 + uint16 0.01 L/min; 0x281 uint16 kPa x4; 0x381 uint16 kPa + status."""
    state = {
        "t_recess": 273.15 + 41.23,
        "t_groove": 273.15 - 5.5,
        "t_supply": 273.15 + 0.01,
        "flow": 12.34e-3 / 60.0,  # 12.34 L/min in m^3/s
        "p_supply": 40_000e3,
        "p_recess": [1e3, 32_768e3, 65_535e3, 0.0],  # u16 kPa, above int16
        "pump_off": True,
    }
    frames = dict(encode_aux(state, sensor_fault=True))
    assert set(frames) == {0x181, 0x281, 0x381}
    assert frames[0x181] == bytes.fromhex("1b10dafd0100d204")  # 4123, -550, 1, 1234
    assert frames[0x281] == bytes.fromhex("409c01000080ffff")  # 40000, 1, 32768, 65535
    assert frames[0x381] == bytes.fromhex("00000300")  # p_recess4 0; sensor fault | pump off
    off = dict(encode_aux(dict(state, pump_off=False)))
    assert off[0x381][2:] == b"\x00\x00"


def test_scan_sizes_follow_the_spec():
    """C must divide 360 in sequential mode only; simultaneous mode takes any C
    that n_ch (u8) can carry."""
    board = AdcBoard(channels=7, mode="simultaneous", frame_slots=3)
    wire = board.encode(0, np.arange(21, dtype=np.int16).reshape(3, 7), np.zeros(3))
    assert wire == golden(0x05, 0, 1, 0, 3, 7, 0, list(range(21)))
    assert AdcBoard(channels=360, mode="sequential").channels == 360
    for channels, mode in ((7, "sequential"), (0, "sequential"), (256, "simultaneous")):
        with pytest.raises(ValueError, match=f"channel count {channels}"):
            AdcBoard(channels=channels, mode=mode)
    cfg = SimConfig(
        adc=AdcConfig(mode="simultaneous", channels=CHANNEL_NAMES[:7], gains=CHANNEL_GAINS[:7], offsets=(0.0,) * 7)
    )
    assert len(cfg.adc.channels) == 7
    with pytest.raises(ValueError, match="must divide 360 in sequential mode"):
        SimConfig(adc=AdcConfig(channels=CHANNEL_NAMES[:7], gains=CHANNEL_GAINS[:7], offsets=(0.0,) * 7))
