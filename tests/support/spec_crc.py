"""The A/D frame's CRC written bit by bit from docs/protocols/adc-frames.md, for the tests that
hold daq and sim to the spec's wire format (neither takes it from the code under test)."""

from __future__ import annotations


def crc16_ccitt_false(data: bytes) -> int:
    """Bitwise CRC-16/CCITT-FALSE: poly 0x1021, init 0xFFFF, no reflection, no final xor."""
    crc = 0xFFFF
    for byte in data:
        crc ^= byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) if crc & 0x8000 else crc << 1
            crc &= 0xFFFF
    return crc
