"""What one read of a drive says, SI: its parameter block (`DriveParameters`) and its process
data (`DriveStatus`, the status word's bits as properties). Pure: drives/drive.py reads them."""

from __future__ import annotations

from dataclasses import dataclass

from drives import registers as R
from rigunits import RPM, in_rpm


@dataclass(frozen=True)
class DriveParameters:
    """The drive's parameter block, SI."""

    speed_scale: float  # rad/s meant by REF = 20000
    max_speed: float  # rad/s, absolute limit (larger references are clamped by the drive)
    accel_time: float  # s from 0 to speed_scale
    decel_time: float  # s from speed_scale to 0
    comm_loss_timeout: float  # s without a request before fault 7510; 0 = disabled
    at_setpoint_band: float  # rad/s

    @classmethod
    def from_words(cls, words: list[int]) -> DriveParameters:
        scale, max_speed, accel, decel, comm, band = words[:6]
        return cls(
            speed_scale=scale * RPM,
            max_speed=max_speed * RPM,
            accel_time=accel * R.TIME_UNIT,
            decel_time=decel * R.TIME_UNIT,
            comm_loss_timeout=comm * R.TIME_UNIT,
            at_setpoint_band=band * RPM,
        )


@dataclass(frozen=True)
class DriveStatus:
    """One read of a drive's process data, SI.

    `reference` and `actual` are rad/s, signed (> 0 forward); `torque` is a
    fraction of nominal; `time` is `time.monotonic()` of the read, `asked` that of its asking
    (its request went out after it).
    """

    name: str
    device_id: int
    control_word: int
    reference: float
    status_word: int
    actual: float
    torque: float
    fault_code: int
    time: float
    reference_raw: int = 0
    actual_raw: int = 0
    asked: float = 0.0

    def _bit(self, bit: R.SWBit) -> bool:
        return bool(self.status_word & bit)

    @property
    def running(self) -> bool:
        """Operation enabled (RDY_REF): following the reference."""
        return self._bit(R.SWBit.RDY_REF)

    @property
    def following(self) -> bool:
        """Running under the run control word: a new REF is all it takes to change speed."""
        return self.running and self.control_word == R.CW_RUN

    @property
    def tripped(self) -> bool:
        return self._bit(R.SWBit.TRIPPED)

    @property
    def at_setpoint(self) -> bool:
        return self._bit(R.SWBit.AT_SETPOINT)

    @property
    def remote(self) -> bool:
        return self._bit(R.SWBit.REMOTE)

    @property
    def stopped(self) -> bool:
        """Actual speed reads exactly zero."""
        return self.actual_raw == 0

    @property
    def emergency_ramp(self) -> bool:
        """Turning in its emergency stop (SW OFF_3_STA 0): a ramp stop word would slow that ramp tenfold."""
        return R.in_emergency_ramp(self.status_word, self.actual_raw)

    @property
    def state(self) -> str:
        return R.state_name(self.status_word)

    @property
    def fault(self) -> str:
        return R.fault_name(self.fault_code)

    def to_dict(self) -> dict[str, object]:
        """JSON-ready summary (speeds in rpm: this is for people and the CLI)."""
        sw = self.status_word
        return {
            "device_id": self.device_id,
            "state": self.state,
            "running": self.running,
            "at_setpoint": self.at_setpoint,
            "tripped": self.tripped,
            "fault_code": self.fault_code,
            "fault": self.fault,
            "reference_rpm": round(in_rpm(self.reference), 3),
            "actual_rpm": round(in_rpm(self.actual), 3),
            "torque_pct": round(100.0 * self.torque, 2),
            "control_word": f"0x{self.control_word:04X}",
            "status_word": f"0x{sw:04X}",
            "status_bits": [b.name for b in R.SWBit if sw & b],
        }
