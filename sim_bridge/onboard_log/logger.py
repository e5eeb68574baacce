"""The built-in vehicle's own log: a DataFlash file (`sim_bridge.onboard_log.dataflash`) in a log folder, as ArduSub
writes one.

Files and rotation as `AP_Logger_File` and `AP_Logger` do them: `DIR/%08u.BIN`, numbered one past LASTLOG.TXT (which
then holds the new number and CRLF); a file starts at arming when LOG_DISARMED is 0 (the default: a re-arm in the
same boot goes on in the same file) and at boot otherwise; LOG_FILE_DSRMROT 1 closes it at disarm (with LOG_DISARMED
0: one file per arming); a reboot closes it. Each file starts with the whole header (`dataflash.header_records`) and
the mode. ARM at each arming and disarming. Data records: ATT, RATE, RCIN, RCOU, CTUN, BARO (the water pressure
sensor, instance 1), XKF1, POS, BAT and, with a rangefinder set up (RNGFND1_TYPE), RFND (ArduSub writes it at
20 Hz from `Sub::read_rangefinder`; here with the rest) at 10 Hz (ArduSub's 10 Hz loop and its medium attitude
rate, `ArduSub.cpp`) while the vehicle is armed, and for HAL_LOGGER_ARM_PERSIST (15 s) after it disarms; MODE at
each mode change; MSG for every text the vehicle sends, and for every STATUSTEXT a station sends it
(`GCS_MAVLINK::handle_statustext`:
"GCS:" before a GCS sysid's text, "SRC=sysid/compid:" before another's); PARM for every parameter set (Default NaN,
as `AP_Logger::Write_Parameter`). ATT's DesRoll/DesPitch/DesYaw and CTUN's DAlt are the attitude and depth the
vehicle holds, NaN where it holds none (MANUAL, ACRO's angles, GUIDED, disarmed). Left out: IMU, XKF2-5, GPS, PID
and the rest a real log carries.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

from sim_bridge.onboard_log.dataflash import FORMATS, header_records, record
from sim_bridge.gcs.telemetry import EARTH_RADIUS, FIRMWARE_VERSION, Snapshot, firmware_string

PERIOD = 0.1                    # s: the 10 Hz records
ARM_PERSIST = 15.0              # s of logging after a disarm (HAL_LOGGER_ARM_PERSIST)
SURFACE_PRESSURE = 101325.0     # Pa
WATER_TEMPERATURE = 15.0        # degC (the bridge simulates none)
FLUSH_PERIOD = 1.0              # s between writes to disk


class OnboardLog:
    """The log folder `directory` of one emulated vehicle; `step(uptime, snapshot, params)` every main-loop pass,
    `text(...)`/`parameter(...)` as they happen, `reboot()` when the power goes, `close()` at the end."""

    def __init__(self, directory: str | Path):
        self.directory = Path(directory)
        self.directory.mkdir(parents=True, exist_ok=True)
        self.file = None
        self.failed = False                  # a write failed: no more logging this bridge's life
        self.path: Path | None = None
        self._buffer: list[bytes] = []
        self._next = 0.0
        self._flushed = 0.0
        self._armed = False
        self._disarmed_at: float | None = None
        self._mode: int | None = None
        self._energy_wh = 0.0
        self._last_t: float | None = None
        self._last_depth: float | None = None

    # -- files ---------------------------------------------------------------------------------------------------

    def _open(self, t: float, snap: Snapshot, params) -> None:
        if self.failed:
            return
        number = self._last_number() + 1
        self.path = self.directory / f"{number:08d}.BIN"
        self.file = open(self.path, "wb")
        (self.directory / "LASTLOG.TXT").write_text(f"{number}\r\n", newline="")
        major, minor, patch = FIRMWARE_VERSION[snap.firmware]
        values = [(s.name, params[s.name], float(s.default)) for s in params.specs]
        text = firmware_string(snap.firmware)
        self._buffer.append(header_records(self._us(t), values, (major, minor, patch), text))
        self._write_mode(t, snap.custom_mode)

    def _last_number(self) -> int:
        try:
            return int((self.directory / "LASTLOG.TXT").read_text().split()[0].rstrip("D"))
        except (OSError, ValueError, IndexError):
            return 0

    def _close(self) -> None:
        self._flush()                 # a failed write has closed the file already
        if self.file is not None:
            self.file.close()
            self.file = None

    def close(self) -> None:
        self._close()

    def reboot(self) -> None:
        """The power goes: the file ends where it is; the next boot starts afresh."""
        self._close()
        self._armed, self._disarmed_at, self._mode, self._last_t = False, None, None, None

    def _flush(self) -> None:
        """Write what is buffered; a write that fails (a full or vanished disk) ends the logging with one line on
        stderr, as ArduPilot's file backend stops on an I/O error, and the vehicle flies on."""
        if self.file is not None and self._buffer:
            try:
                self.file.write(b"".join(self._buffer))
                self.file.flush()
            except OSError as exc:
                print(f"sim-bridge: the on-board log stopped: {self.path}: {(exc.strerror or str(exc)).lower()}",
                      file=sys.stderr, flush=True)
                self.failed = True
                file, self.file = self.file, None
                try:
                    file.close()
                except OSError:
                    pass
        self._buffer = []

    # -- what happens ------------------------------------------------------------------------------------------

    def step(self, t: float, armed: bool, mode: int, snap_of, params) -> None:
        """One main-loop pass at time since boot t, armed or not, in `mode`; `snap_of()` gives the vehicle's
        Snapshot when a record needs it."""
        rotate = params["LOG_FILE_DSRMROT"] > 0
        if armed and not self._armed:
            self._disarmed_at = None
            if self.file is None:
                self._open(t, snap_of(), params)
            self._arm_record(t, True)
        elif not armed and self._armed:
            self._disarmed_at = t
            self._arm_record(t, False)
            if rotate:
                self._close()
        self._armed = armed
        if self.file is None and params["LOG_DISARMED"] > 0:
            self._open(t, snap_of(), params)
        if self.file is None:
            return
        if mode != self._mode:
            self._write_mode(t, mode)
        if t >= self._next and (armed or params["LOG_DISARMED"] > 0 or self._persisting(t)):
            self._next = t + PERIOD
            self._data(t, snap_of())
        if t - self._flushed >= FLUSH_PERIOD:
            self._flushed = t
            self._flush()

    def _arm_record(self, t: float, armed: bool) -> None:
        """ARM (`AP_Arming::Log_Write_Arm` / `Log_Write_Disarm`): the state, checks, forced, method (not known)."""
        if self.file is not None:
            self._buffer.append(record(FORMATS["ARM"], self._us(t), int(armed), 0, 0, 0))

    def _persisting(self, t: float) -> bool:
        return self._disarmed_at is not None and t - self._disarmed_at <= ARM_PERSIST

    def _write_mode(self, t: float, mode: int) -> None:
        self._mode = mode
        self._buffer.append(record(FORMATS["MODE"], self._us(t), mode, mode, 0))

    def text(self, t: float, text: str) -> None:
        """A MSG record (the vehicle's own text, or a station's with its prefix)."""
        if self.file is not None:
            self._buffer.append(record(FORMATS["MSG"], self._us(t), text[:64]))

    def parameter(self, t: float, name: str, value: float) -> None:
        if self.file is not None:
            self._buffer.append(record(FORMATS["PARM"], self._us(t), name, value, math.nan))

    @staticmethod
    def _us(t: float) -> int:
        return max(int(round(t * 1e6)), 0)

    def _data(self, t: float, s: Snapshot) -> None:
        us = self._us(t)
        roll, pitch, yaw = (math.degrees(a) for a in s.eta[3:6])
        target_roll, target_pitch, target_yaw = (math.degrees(a) for a in s.targets[:3])   # NaN: not held
        target_depth = s.targets[3]
        p, q, r = (math.degrees(w) for w in s.nu[3:6])
        v = s.ned_velocity()
        depth = float(s.eta[2])
        bar30 = depth if s.bar30_depth is None else s.bar30_depth
        climb = 0.0 if self._last_depth is None or self._last_t is None or t <= self._last_t else \
            -(bar30 - self._last_depth) / (t - self._last_t)
        if self._last_t is not None and t > self._last_t:
            self._energy_wh += s.voltage * s.current * (t - self._last_t) / 3600.0
        self._last_t, self._last_depth = t, bar30
        lat0, lon0, alt0 = s.origin
        lat = lat0 + math.degrees(float(s.eta[0]) / EARTH_RADIUS)
        lon = lon0 + math.degrees(float(s.eta[1]) / (EARTH_RADIUS * math.cos(math.radians(lat0))))
        pressure = SURFACE_PRESSURE + s.water_density * s.gravity * bar30
        f = FORMATS
        self._buffer += [
            record(f["ATT"], us, target_roll, roll, target_pitch, pitch, target_yaw % 360.0, yaw % 360.0, 3),
            record(f["RATE"], us, 0.0, p, 0.0, 0.0, q, 0.0, 0.0, r, 0.0, 0.0, -v[2] * 100.0, s.throttle, 0.0),
            record(f["RCIN"], us, *np.asarray(s.rc_in[:14], dtype=float)),
            record(f["RCOU"], us, *np.asarray(s.servo[:14], dtype=float)),
            record(f["CTUN"], us, s.throttle, 0.0, s.throttle, 0.5, -target_depth, -depth, -bar30, math.nan, math.nan,
                   0.0, 0, -v[2] * 100.0),
            record(f["BARO"], us, 1, -bar30, alt0 - bar30, pressure, WATER_TEMPERATURE, climb, us // 1000, 0.0,
                   WATER_TEMPERATURE, int(s.depth_healthy)),
            record(f["XKF1"], us, 0, roll, pitch, yaw % 360.0, v[0], v[1], v[2], v[2], s.eta[0], s.eta[1], depth,
                   0.0, 0.0, 0.0, 0.0),
            record(f["POS"], us, lat, lon, alt0 - depth, -depth, -depth),
            record(f["BAT"], us, 0, s.voltage, s.voltage, s.current, s.consumed_ah * 1000.0, self._energy_wh, 0.0,
                   0.0, round(100.0 * s.remaining), 1, 100),
        ]
        if s.rangefinder_log is not None:
            distance, status, orientation, quality = s.rangefinder_log
            self._buffer.append(record(f["RFND"], us, 0, distance, status, orientation, quality))

