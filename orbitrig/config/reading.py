"""A configuration file read: its bytes as UTF-8 text (no byte order mark), its TOML, its model
validated (one message per problem, at its line: orbitrig.config.messages), and the file an
option names or the default one, or what to give instead. Each failure a ConfigError naming the file."""

from __future__ import annotations

import tomllib
import warnings
from pathlib import Path

from pydantic import ValidationError

from orbitrig.config.fields import FileConfig
from orbitrig.config.home import HOME_ENV
from orbitrig.config.messages import problem_lines, bom_problem, reissue
from orbitrig.errors import ConfigError


def parse_toml(text: str, file: str) -> dict:
    """The TOML tables of a configuration file's text, or ConfigError naming ``file``."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise ConfigError(file, [f"not valid TOML: {err}"]) from err
    except RecursionError:
        raise ConfigError(file, ["not valid TOML: arrays or tables nested too deeply"]) from None


def build_model(cls, data: dict, file: str, text: str):
    """``cls`` validated from the file's tables, a FileConfig remembering ``file`` and ``text``;
    its problems a ConfigError, one message per problem at its line; its warnings reissued at theirs."""
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            obj = cls.model_validate(data)
    except ValidationError as err:
        raise ConfigError(file, problem_lines(err, cls, text)) from err
    reissue(caught, file, text)  # at the line of the file they concern
    if isinstance(obj, FileConfig):  # (a calibration record's reader hands its text on beside it)
        obj.remember_file(file, text)
    return obj


def read_text(path: Path | str) -> tuple[str, str]:
    """(UTF-8 text, path) of a configuration file, or ConfigError naming it."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as err:
        raise ConfigError(str(path), [f"cannot read the file: {err.strerror or err}"]) from err
    return decode_text(data, str(path)), str(path)


def decode_text(data: bytes, file: str) -> str:
    """UTF-8 text of a configuration file, or ConfigError naming the line and byte (or the byte
    order mark that TOML forbids)."""
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as err:
        line = data.count(b"\n", 0, err.start) + 1
        raise ConfigError(
            file, [f"line {line}: not UTF-8 text ({err.reason} at byte {err.start}); save the file as UTF-8"]
        ) from None
    bom = bom_problem(text)
    if bom is not None:
        raise ConfigError(file, [bom])
    return text


#: what to give instead of a file that is not there, by option
_WHAT_TO_GIVE = {
    "--config": "a rig.toml (`orbitrig init DIR` writes DIR/rig.toml to edit)",
    "--matrix": "a matrix TOML file or the name of one in the configuration's matrices/",
}


def read_given_or_default(path: Path | str | None, default: Path, option: str) -> tuple[str, str]:
    """(UTF-8 text, path) of the file ``option`` names (``path``), else of ``default``; a folder, a
    missing file or no default is a ConfigError saying what to give instead."""
    if path is not None and (Path(path).is_dir() or not Path(path).exists()):
        found = "is a folder" if Path(path).is_dir() else "no such file"
        raise ConfigError(str(path), [f"{found}: give {option} {_WHAT_TO_GIVE[option]}"])
    if path is not None or default.is_file():
        return read_text(path or default)
    raise ConfigError(
        str(default),
        [
            f"the default file is not there: give {option} FILE, set {HOME_ENV} to a "
            "folder made by `orbitrig init DIR`, or run in such a folder"
        ],
    )
