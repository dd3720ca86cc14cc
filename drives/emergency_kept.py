"""An emergency stop kept against a ramp stop word that reaches a drive after it.

The contract has OFF3 = 0 as the fastest ramp stop and says nothing of a control word releasing
OFF3 during it. Assumed the worst it allows: a ramp stop word (OFF1: 0x047E, OFF3 released) written
after OFF3 turns the drive's emergency ramp back into its ramp stop along DECEL_TIME, ten times
slower (the simulator's `DriveModel.off1_yields` behaves so). Such a word can come late: a ramp
stop's word the link gave up on (drives/late.py) reaching the drive after the abort's OFF3; or
from another client. So, after an emergency stop both drives took or owe (the last stop sent was
OFF3), a drive read still turning with the ramp stop word in CW, by a read asked after that stop
ended, gets the emergency stop again (`off3_released`: a warning, naming the ramp stop word given
up when one may still arrive). Not a failure: what the abort itself found stands.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

from drives import registers as R
from drives.late import LateWrites, said_all
from drives.limits import fmt_speed
from rigunits import utc_iso

if TYPE_CHECKING:
    from drives.drive import DriveStatus


def off3_released(statuses: Sequence[DriveStatus], late: LateWrites, since: float) -> list[str]:
    """Warnings for the drives of `statuses` read (asked after `since`, monotonic s: the end of the
    emergency stop) still turning with the ramp stop word in CW: each gets the emergency stop again.
    The cause named: a ramp stop word given up to it and open at the read, else another client."""
    found = []
    for st in statuses:
        if st.asked <= since or st.stopped or st.control_word != R.CW_RAMP_STOP:
            continue
        given = [g for g in late.open([st.device_id], at=st.asked) if g.stop and g.values == (R.CW_RAMP_STOP,)]
        who = (
            f"most likely our own ramp stop word given up unanswered at {utc_iso(given[0].wall)} "
            f"({said_all(given)}) reached it late (else another client wrote the same word)"
            if given
            else "another client wrote it"
        )
        found.append(
            f"{st.name} drive (id {st.device_id}): CW (0) reads the ramp stop word 0x{R.CW_RAMP_STOP:04X}, "
            f"ACT {fmt_speed(st.actual)}, after the emergency stop: {who}; the emergency stop (OFF3) is "
            "written again (a ramp stop word after OFF3 may turn the emergency ramp into the ten times "
            "slower ramp stop)"
        )
    return found
