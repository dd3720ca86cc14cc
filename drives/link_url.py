"""The Modbus URL of a drive link: `tcp://host:port` or `rtu:///dev/ttyS0?baud=19200`."""

from __future__ import annotations

from dataclasses import dataclass
from urllib.parse import parse_qs, urlsplit

from drives.errors import DriveLinkError


@dataclass(frozen=True)
class LinkAddress:
    """A parsed Modbus URL."""

    kind: str  # "tcp" | "rtu"
    host: str = ""  # tcp
    port: int = 0  # tcp
    path: str = ""  # rtu: serial device
    baud: int = 19200  # rtu


def parse_modbus_url(url: str) -> LinkAddress:
    """Parse `tcp://host:port` (port 502 if omitted) or `rtu:///dev/ttyS0?baud=19200`.

    Raises DriveLinkError naming what is wrong with the URL.
    """
    try:
        parts = urlsplit(url)
        query = parse_qs(parts.query, strict_parsing=bool(parts.query))
        if parts.scheme == "tcp":
            if query:
                raise ValueError(f"unexpected query {parts.query!r}")
            if not parts.hostname:
                raise ValueError("no host")
            return LinkAddress("tcp", host=parts.hostname, port=parts.port or 502)
        if parts.scheme == "rtu":
            if not parts.path or parts.netloc:
                raise ValueError("expected rtu:///dev/<serial device>")
            unknown = set(query) - {"baud"}
            if unknown:
                raise ValueError(f"unknown option(s) {', '.join(sorted(unknown))}; only baud")
            baud = int(query.get("baud", ["19200"])[-1])
            if baud <= 0:
                raise ValueError(f"baud {baud} is not positive")
            return LinkAddress("rtu", path=parts.path, baud=baud)
        raise ValueError(f"unknown scheme {parts.scheme!r}; use tcp:// or rtu://")
    except ValueError as err:
        raise DriveLinkError(f"bad Modbus URL {url!r}: {err}") from err
