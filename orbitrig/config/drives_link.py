"""The drives' link as a refused rig.toml still gives it: `[transports] modbus_url` and the
`[drives]` keys that hold on their own, for `drives stop` and `drives status` (a stop must not
wait for a typo elsewhere in the file). Each is checked as the full load checks it (the same
models and messages), with the rest of the file left aside. The URL and the ids are hardware keys:
one left out (or misspelt) is refused as the full load refuses it, never taken from the defaults
(the simulator's address and ids); another [drives] key left out takes its default."""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from pathlib import Path

from pydantic import ValidationError

from orbitrig.config.drives_section import Drives
from orbitrig.config.fields import ConfigModel
from orbitrig.config.hardware import HARDWARE_KEYS, missing_hardware
from orbitrig.config.messages import problem_lines
from orbitrig.config.rig import Transports

IDS = ("spin_id", "orbit_id")


class _Link(ConfigModel):
    """The two sections of RigConfig the drives' link is taken from, as RigConfig checks them."""

    transports: Transports = Transports()
    drives: Drives = Drives()


@dataclass(frozen=True)
class DrivesLink:
    """What a rig.toml gives the drives' link: ``url`` (None: refused), ``drives`` (the [drives]
    keys that hold, the others at their defaults; None: a device id refused), ``file``, and
    ``problems``: why the URL or an id was refused, each naming its line and key."""

    file: str
    url: str | None
    drives: Drives | None
    problems: list[str] = field(default_factory=list)


def drives_link(path: Path | str | None) -> DrivesLink:
    """The drives' link of the rig configuration ``path`` (default the lab's); ConfigError if the
    file cannot be read or is not TOML (nothing can be taken from it)."""
    from orbitrig.config import default_rig_path
    from orbitrig.config.reading import parse_toml, read_given_or_default

    text, file = read_given_or_default(path, default_rig_path(), "--config")
    data = parse_toml(text, file)
    transports = data.get("transports", {})
    url_problems = _missing(data, text, "transports", ("modbus_url",))
    if not url_problems:
        given = {"modbus_url": transports["modbus_url"]} if isinstance(transports, dict) else transports
        url_problems = _refused({"transports": given}, text)
    url = None if url_problems else transports["modbus_url"]
    id_problems = _missing(data, text, "drives", IDS)
    drives, more = (None, []) if id_problems else _drives_of(data.get("drives", {}), text)
    return DrivesLink(file, url, drives, url_problems + id_problems + more)


def _missing(data: dict, text: str, section: str, keys: tuple[str, ...]) -> list[str]:
    """The full load's messages for the hardware ``keys`` of [section] the file leaves out."""
    return missing_hardware(data, text, {section: {k: HARDWARE_KEYS[section][k] for k in keys}})


def _drives_of(section, text: str) -> tuple[Drives | None, list[str]]:
    """([drives] with its ids and every other key that holds with them, the problems of the ids)."""
    if not isinstance(section, dict):
        return None, _refused({"drives": section}, text)
    ids = {k: section[k] for k in IDS if k in section}
    problems = _refused({"drives": ids}, text)
    if problems:
        return None, problems
    kept = ids | {k: v for k, v in section.items() if k not in IDS and not _refused({"drives": ids | {k: v}}, text)}
    if _refused({"drives": kept}, text):  # keys that hold alone but not together (link loss vs watchdog)
        kept = ids
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the full load says them
        return Drives.model_validate(kept), []


def _refused(data: dict, text: str) -> list[str]:
    """The full load's messages for ``data``, [transports] and [drives] keys (the rest at their defaults)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            _Link.model_validate(data)
        except ValidationError as err:
            return problem_lines(err, _Link, text)
    return []
