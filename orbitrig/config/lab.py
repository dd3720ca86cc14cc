"""Write a lab configuration folder from the shipped defaults (`orbitrig init DIR`).

The folder holds what a lab edits: ``rig.toml``, ``matrices/``, ``designs/``, a
``calibration/`` folder for the channels' calibration records, and ``mosquitto/`` (the
broker's configuration, ACL, example password file and README) whose paths (the README's
commands too) point into the folder or into the broker folder given (``--broker-dir``, e.g. /etc/mosquitto/orbitrig when the
files are installed there). Later commands find the folder as orbitrig.config.home says.
"""

from __future__ import annotations

import re
import shlex
import shutil
from pathlib import Path

from orbitrig.config.home import DESIGNS, MATRICES, RIG_FILE, shipped_config
from orbitrig.errors import ConfigError
from orbitrig.config.record_files import RECORD_KEY, list_names, read_record, write_dated

#: the rig_id of the shipped rig.toml: a lab that keeps it cannot be told from another by it
SHIPPED_RIG_ID = "SAC-DS-1"
#: what a rig_id given to init may hold
RIG_ID_PATTERN = r"[A-Za-z0-9][A-Za-z0-9._-]{0,63}"

MOSQUITTO = "mosquitto"
CALIBRATION = "calibration"
#: the operator of the initial record init writes (nobody calibrated: the values are typed in)
INIT_OPERATOR = "orbitrig init"
INITIAL_HEADER = """\
orbitrig calibration record (docs/calibration.md): this rig's initial calibration, written by
`orbitrig init` on {day} when the lab folder was made: the type-B uncertainties of the sensors'
data sheets and certificates. Nothing is measured yet (no gain matrices, runout or lags): its date
is when it was written, not a calibration's. `orbitrig calibrate` steps write the measured records.
Units: gain_pct percent, phase_deg degrees, delay_us microseconds (standard uncertainties, k = 1)."""
_BROKER_FILES = ("acl", "passwd.example")
#: the broker folder the shipped mosquitto.conf and README.md name (rewritten by init)
SHIPPED_BROKER_DIR = "/etc/mosquitto/orbitrig"
#: the persistence folder the shipped mosquitto.conf and README.md name (Debian's; init: the broker folder's data/)
SHIPPED_PERSISTENCE = "/var/lib/mosquitto/"
# mosquitto.conf keys that name a file (or folder) of the broker, and the file they name
_BROKER_PATHS = {
    "password_file": "passwd",
    "acl_file": "acl",
    "cafile": "ca.crt",
    "certfile": "broker.crt",
    "keyfile": "broker.key",
    "persistence_location": "data/",
}
_CALIBRATION_README = """\
# Calibration records

One TOML file per calibration step, named by its UTC date (`orbitrig calibrate
loads|runout|delay|probes` writes them; `orbitrig calibrate list` shows the
history). ../rig.toml names the active one (`calibration_record`); its values
correct the forces and displacements and its [uncertainty] enters every
coefficient's uncertainty budget. Keep the reference certificates beside them.
"""


def write_lab(
    folder: Path, broker_dir: Path | None = None, force: bool = False, rig_id: str | None = None
) -> list[Path]:
    """Write the lab configuration into ``folder``; the files written, in order. ``rig_id``: this
    rig's identifier in its rig.toml (None: the shipped example's, SHIPPED_RIG_ID).

    Raises ConfigError if ``folder`` is a file, already holds a rig.toml and ``force`` is false, or
    ``rig_id`` is not a RIG_ID_PATTERN word."""
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():  # else "DIR/rig.toml: cannot write: File exists"
        raise ConfigError(str(folder), ["not a folder (a file is there): give a new or existing folder for the lab"])
    if (folder / RIG_FILE).exists() and not force:
        raise ConfigError(
            str(folder / RIG_FILE), ["already there: a lab configuration exists in this folder (--force overwrites it)"]
        )
    if rig_id is not None and not re.fullmatch(RIG_ID_PATTERN, rig_id):
        raise ConfigError("--rig-id", [f"{rig_id!r}: give letters, digits and . _ - only (e.g. SAC-DS-2)"])
    shipped = shipped_config()
    rig_text = (shipped / RIG_FILE).read_text(encoding="utf-8")
    if rig_id is not None:
        rig_text = re.sub(r'(?m)^rig_id = "[^"]*"', f'rig_id = "{rig_id}"', rig_text, count=1)
    initial = _initial_record(shipped, folder / CALIBRATION, rig_id or SHIPPED_RIG_ID)
    rig_text = RECORD_KEY.sub(lambda m: f'{m.group(1)}"{initial.stem}"', rig_text, count=1)
    written = [_write(folder / RIG_FILE, rig_text)]
    for kind in (MATRICES, DESIGNS):
        written += [_copy(f, folder / kind / f.name) for f in sorted((shipped / kind).glob("*.toml"))]
    written += [_copy(shipped / MOSQUITTO / name, folder / MOSQUITTO / name) for name in _BROKER_FILES]
    broker = (broker_dir or folder / MOSQUITTO).resolve()
    conf = broker_conf((shipped / MOSQUITTO / "mosquitto.conf").read_text(encoding="utf-8"), broker)
    readme = broker_readme((shipped / MOSQUITTO / "README.md").read_text(encoding="utf-8"), broker)
    written.append(_write(folder / MOSQUITTO / "README.md", readme))
    written.append(_write(folder / MOSQUITTO / "mosquitto.conf", conf))
    (folder / MOSQUITTO / "data").mkdir(exist_ok=True)
    written.append(initial)
    written.append(_write(folder / CALIBRATION / "README.md", _CALIBRATION_README))
    return written


def _initial_record(shipped: Path, records: Path, rig: str) -> Path:
    """The lab's initial record in ``records``: the shipped one's data-sheet uncertainties, dated
    now, when init writes it (the shipped record's own date is the example's, older than the lab),
    its header saying that this date is no calibration's; the file written. An init --force within
    the second of the last one dates it at the next free second (write_dated; the earlier stays)."""
    folder = shipped / CALIBRATION
    (name,) = [n for n in list_names(folder) if n.endswith("-initial")]
    record, _ = read_record(folder, name)
    fresh = record.model_copy(update={"operator": INIT_OPERATOR, "rig": rig})
    _, written, _ = write_dated(records, fresh, lambda dated: INITIAL_HEADER.format(day=dated.date[:10]))
    return records / f"{written}.toml"


def broker_conf(text: str, broker: Path) -> str:
    """The shipped mosquitto.conf with every file it names in the folder ``broker``."""

    def repoint(match: re.Match) -> str:
        name = _BROKER_PATHS[match["key"]]
        target = str(broker / name) + ("/" if name.endswith("/") else "")
        return f"{match['hash']}{match['key']} {target}"

    keys = "|".join(_BROKER_PATHS)
    return re.sub(rf"^(?P<hash>#?)(?P<key>{keys}) \S+$", repoint, text, flags=re.MULTILINE)


def broker_readme(text: str, broker: Path) -> str:
    """The shipped broker README with every file of SHIPPED_BROKER_DIR it names (the password
    file its commands create) and the persistence folder in the folder ``broker``, as
    broker_conf puts them: quoted for the shell where the path needs it."""
    text = text.replace(SHIPPED_PERSISTENCE, shlex.quote(str(broker / _BROKER_PATHS["persistence_location"]) + "/"))
    return re.sub(
        rf"{re.escape(SHIPPED_BROKER_DIR)}/(?P<name>[\w.-]+)", lambda m: shlex.quote(str(broker / m["name"])), text
    )


def _copy(src: Path, dst: Path) -> Path:
    try:
        dst.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(src, dst)
    except OSError as err:
        raise ConfigError(str(dst), [f"cannot write: {err.strerror or err}"]) from err
    return dst


def _write(dst: Path, text: str) -> Path:
    try:
        dst.parent.mkdir(parents=True, exist_ok=True)
        dst.write_text(text, encoding="utf-8")
    except OSError as err:
        raise ConfigError(str(dst), [f"cannot write: {err.strerror or err}"]) from err
    return dst
