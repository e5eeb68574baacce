"""What a run changed on the vehicle, recorded as it changes it, for the safe stop to undo step by step."""

from __future__ import annotations

from dataclasses import dataclass, field

PASSTHROUGH_BASE = 50            # SERVOn_FUNCTION 50 + n = RCINn


@dataclass
class VehicleChanges:
    """Each field one kind of change and what undoes it (`flight.run.safe_stop`)."""

    saved_functions: dict[str, tuple[float, int]] = field(default_factory=dict)   # SERVOn_FUNCTION: (to restore, type)
    functions: list[str] = field(default_factory=list)   # SERVOn_FUNCTION switched to (or found on) passthrough
    gcs: tuple[str, int, int] | None = None   # the GCS sysid parameter changed for the run: (name, was, type)
    gcs_high: tuple[int, int] | None = None   # MAV_GCS_SYSID_HI set to 0 for the run: (was, type)
    overrides_sent: bool = False     # an RC override (neutral included) went out: released at the end
    armed: bool = False              # armed by this run: disarmed at the end (left armed when handing over)
    streams: list[int] = field(default_factory=list)   # message ids whose interval was set: reset to the defaults
    mode_found: int | None = None    # the mode found before the run set GUIDED: set back at the end

    @property
    def anything(self) -> bool:
        """Did the run change anything that a stop must undo (message rates aside)?"""
        return bool(self.overrides_sent or self.functions or self.armed or self.gcs is not None
                    or self.gcs_high is not None)

    def gcs_values(self) -> dict[str, tuple[float, int]]:
        """The GCS sysid parameters to set back (after the outputs are on their motors)."""
        values = {}
        if self.gcs is not None:
            values[self.gcs[0]] = (float(self.gcs[1]), self.gcs[2])
        if self.gcs_high is not None:
            values["MAV_GCS_SYSID_HI"] = (float(self.gcs_high[0]), self.gcs_high[1])
        return values

    def restore_values(self) -> dict[str, tuple[float, int]]:
        """The SERVOn_FUNCTION values to set back."""
        return {name: self.saved_functions[name] for name in self.functions}
