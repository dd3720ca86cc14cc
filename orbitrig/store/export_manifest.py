"""The files a csv export wrote, listed in ``csv_manifest.txt`` in its folder, so that the next
csv export into that folder removes the earlier one's files it does not write again (a point no
longer exported would otherwise leave its ``point_PPPP_<lms>.csv``, ``covariance_...``,
``derived_...`` and ``runout_turns_PPPP.csv`` looking current).

Only a file the earlier manifest lists, named as the csv export names its files (a plain name,
PATTERN) and still a file, is ever removed: never one the exporter did not write. A per-point
look-alike not written by this export nor listed (e.g. from an export before manifests) is left
and named. The manifest is replaced atomically; before a removal it lists the files to remove
too, so an export cut short removes them next time.
"""

from __future__ import annotations

import re
from pathlib import Path

from orbitrig.store.durable import fsync_dir, write_atomic
from orbitrig.store.errors import storage_error

MANIFEST = "csv_manifest.txt"
#: the names a csv export gives its files
_PER_POINT = re.compile(r"(point|covariance|derived)_\d+_[\w.-]+\.csv|runout_turns_\d+\.csv")
PATTERN = re.compile(rf"{_PER_POINT.pattern}|(coefficients|fits|fit_properties|provenance)\.csv")
HEADER = "# the files the last `orbitrig export --format csv` wrote into this folder, one per line"


def _read(out: Path) -> set[str] | None:
    """The names the folder's manifest lists (None: no manifest)."""
    try:
        text = (out / MANIFEST).read_text(encoding="utf-8")
    except FileNotFoundError:
        return None
    except (OSError, UnicodeDecodeError) as err:
        raise storage_error(out / MANIFEST, "read the earlier export's manifest", err) from err
    return {line.strip() for line in text.splitlines() if line.strip() and not line.startswith("#")}


def listed(out: Path) -> set[str]:
    """The file names the manifest in ``out`` lists (empty without one)."""
    return _read(Path(out)) or set()


def _ours(out: Path, name: str) -> bool:
    """A plain file name of the csv export's, a file in ``out``."""
    return Path(name).name == name and PATTERN.fullmatch(name) is not None and (out / name).is_file()


def _write(out: Path, names: list[str]) -> None:
    write_atomic(out / MANIFEST, ("\n".join([HEADER, *names]) + "\n").encode("utf-8"))


def replace_earlier(out: Path, written: list[Path]) -> list[str]:
    """List ``written`` (files in ``out``) in the manifest and remove the earlier manifest's
    files not written again; what was removed, and each look-alike left, as notes. Raises
    StorageError naming a file that cannot be removed or the manifest."""
    earlier = _read(out)
    names = [p.name for p in written]
    stale = sorted(n for n in (earlier or set()) - set(names) if _ours(out, n))
    notes = []
    if stale:
        _write(out, names + stale)  # cut short before the removal: the next export removes them
        for name in stale:
            try:
                (out / name).unlink()
            except FileNotFoundError:
                continue
            except OSError as err:
                raise storage_error(out / name, "remove a file of the earlier export", err) from err
            notes.append(f"removed {out / name}: written by the earlier csv export, not by this one")
        fsync_dir(out)
    _write(out, names)
    why = " (no earlier manifest)" if earlier is None else " nor listed by the earlier one"
    left = sorted(p.name for p in out.iterdir() if _PER_POINT.fullmatch(p.name) and p.name not in names and p.is_file())
    return notes + [f"{out / n} was not written by this export{why}: left as it is" for n in left]
