"""Modbus RTU request framing on a byte stream without line timing (a pty).

Pure bytes, no I/O: the CRC-16 of the Modbus serial line and `find_request`,
which finds the next complete, CRC-valid request in a receive buffer by its
function code's size and its CRC, hunting byte by byte past noise. Every
well-formed request is found, also several back to back in one read (what
pymodbus' RTU framer loses: it consumes the whole receive buffer with the
first frame). `sim/modbus_server.py` serves the requests it finds.
"""

from __future__ import annotations

__all__ = ["MAX_ADU", "crc16", "find_request", "with_crc"]

# Request sizes (bytes, device id and CRC included) by function code, from the
# Modbus application protocol: a fixed size, or (position of the byte count,
# bytes around it). Other function codes are framed by their CRC alone.
_FIXED_SIZE = {1: 8, 2: 8, 3: 8, 4: 8, 5: 8, 6: 8, 7: 4, 8: 8, 11: 4, 12: 4, 17: 4, 22: 10, 24: 6}
_COUNTED_SIZE = {15: (6, 9), 16: (6, 9), 20: (2, 5), 21: (2, 5), 23: (10, 13)}
MAX_ADU = 256


def _crc_table() -> list[int]:
    table = []
    for byte in range(256):
        crc = byte
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
        table.append(crc)
    return table


_CRC_TABLE = _crc_table()


def crc16(data: bytes | bytearray | memoryview) -> int:
    """Modbus CRC-16 (poly 0xA001 reflected, init 0xFFFF); sent low byte first."""
    crc = 0xFFFF
    for b in data:
        crc = (crc >> 8) ^ _CRC_TABLE[(crc ^ b) & 0xFF]
    return crc


def with_crc(body: bytes) -> bytes:
    """`body` followed by its CRC, low byte first."""
    return body + crc16(body).to_bytes(2, "little")


def find_request(buf: bytes | bytearray) -> tuple[int, int] | None:
    """(start, end) of the first complete, CRC-valid request frame in `buf`, or None.

    Hunts byte by byte: bytes before `start` are line noise or the fragment of a
    broken frame (a real RTU receiver drops them at the next inter-frame
    silence). Every complete frame is found, also several back to back in one
    read; an incomplete frame at the head does not hide a complete one after it.
    """
    n = len(buf)
    for k in range(n - 3):
        fc = buf[k + 1]
        if fc in _FIXED_SIZE:
            size = _FIXED_SIZE[fc]
        elif fc in _COUNTED_SIZE:
            pos, extra = _COUNTED_SIZE[fc]
            if k + pos >= n:
                continue
            size = buf[k + pos] + extra
        else:  # unknown layout: the shortest CRC-valid frame
            crc = 0xFFFF
            for e in range(k, min(n, k + MAX_ADU) - 2):
                crc = (crc >> 8) ^ _CRC_TABLE[(crc ^ buf[e]) & 0xFF]
                if e - k >= 1 and crc == buf[e + 1] | buf[e + 2] << 8:
                    return k, e + 3
            continue
        end = k + size
        if end <= n and crc16(buf[k : end - 2]) == buf[end - 2] | buf[end - 1] << 8:
            return k, end
    return None
