"""`rov-mav sim-bridge`: run the simulated ArduSub BlueROV2 Heavy until Ctrl-C or SIGTERM."""

from __future__ import annotations

import argparse
import signal
import sys

from rov_mav.commands.arguments import endpoint, mission_file, number, seed, speedup, vehicle_file
from rov_mav.commands.common import VEHICLE_HELP, add_signing_options, signing_key
from rov_mav.model.environment import load_environment
from rov_mav.model.navigation import PRESET_NAMES, Navigation, NavigationError, load_navigation
from rov_mav.model.vehicle_faults import VehicleFaultError, VehicleFaults, load_vehicle_faults
from sim_bridge.config import DEFAULT_ORIGIN, DEFAULT_OUT, DEFAULT_STEP, BridgeConfig
from sim_bridge.transport.faults import FaultError, FaultSpec, load_faults
from sim_bridge.transport.link import TransportError
from sim_bridge.autopilot.params import DEFAULT_FIRMWARE, FIRMWARES

DESCRIPTION = """\
A simulated BlueROV2 Heavy that speaks ArduSub's MAVLink (MAVLink 2), so that a ground station (QGroundControl,
MAVProxy), MAVSDK or `rov-mav run` can fly it as they would a real one or ArduSub SITL.

What it emulates: HEARTBEAT as ArduSub (submarine, modes MANUAL/STABILIZE/ACRO/ALT_HOLD/POSHOLD/GUIDED/SURFACE/
SURFTRAK/AUTO, the assisted ones holding attitude, depth and position with simple loops of its own, AUTO flying the
stored mission's waypoints at a depth or above the bottom; other modes refused),
arming and
DO_SET_MODE/SET_MODE with COMMAND_ACK, parameters (PARAM_*) with ArduSub's names and defaults,
SET_MESSAGE_INTERVAL / REQUEST_MESSAGE / REQUEST_DATA_STREAM, RC_CHANNELS_OVERRIDE exactly as ArduSub treats it
(only from the GCS sysid, expiry after RC_OVERRIDE_TIME), MANUAL_CONTROL with its buttons, the frame FRAME_CONFIG
names at start (2, a BlueROV2 Heavy, unless told: --param FRAME_CONFIG=1 is a standard BlueROV2's six motors, on the
Heavy's hull), SERVOn_FUNCTION routing (33..40 motors through the frame's mixer when armed; 51..66 RCIN
passthrough, NOT gated by arming and holding its last value when the
overrides stop), the GCS-heartbeat, pilot-input, leak (FS_LEAK_ENABLE), battery (BATT_LOW_VOLT/CRT_VOLT/_MAH,
BATT_FS_LOW_ACT/CRT_ACT), EKF (FS_EKF_ACTION/THRESH) and depth-sensor failsafes, SURFACE mode (rises to the
surface, then ALT_HOLD), MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN, and telemetry (ATTITUDE, LOCAL_POSITION_NED,
GLOBAL_POSITION_INT, SCALED_PRESSURE2, VFR_HUD, SERVO_OUTPUT_RAW, RC_CHANNELS, SYS_STATUS, BATTERY_STATUS,
EKF_STATUS_REPORT, ...). The vehicle is the project's 6-DOF model with T200 thrusters (PWM -> thrust at the
battery voltage, 20 ms lag).

Vehicle faults (--vehicle-faults, or an --environment file's vehicle_faults:) strike at vehicle times since the
bridge started: a thruster dead, stuck, weak or reversed; a reboot (a brown-out: TCP clients dropped, 2 s of
silence, time_boot_ms from 0, HEARTBEAT BOOT, then "ArduPilot Ready" 3 s after the power loss: disarmed, MANUAL,
stored parameters); a leak; a sagging battery; the horizontal position source lost (the EKF's position flags drop
after 7 s, constant-position mode and no LOCAL_POSITION_NED after 15 s); a failed depth sensor ("Depth sensor
error!", depth modes to MANUAL). Each meets ArduSub's own reaction, with its parameters and defaults.

The water may have a bottom and an ice ceiling (an --environment file's seafloor: and ice:: flat, a slope, steps, a
profile, seeded relief) and the vehicle an echo sounder (its navigation's echo_sounder: ping, ideal or its figures):
the sounder's DISTANCE_SENSOR comes from the companion (1/194) as BlueOS's Ping service sends it, RNGFND1_TYPE is set
to 10, and the autopilot's rangefinder feeds SURFTRAK (the range held as ArduSub's mode_surftrak.cpp holds it), its
own DISTANCE_SENSOR and RFTarget. The true height above the bottom (NAMED_VALUE_FLOAT SimHeight) goes beside
SIM_STATE.

Every timer (failsafes, override expiry, telemetry rates, time_boot_ms) runs on the simulated clock, which runs
--speedup times faster than the wall clock: at --speedup 10, send heartbeats and overrides 10x as often.
The simulation's own settings are parameters too: SIM_SPEEDUP (changes the pace at once), SIM_BATT_VOLTAGE
and SIM_BATT_CAP_AH (full-charge voltage and capacity, read at start: set them with --param).
"""

EPILOG = """\
examples:
  rov-mav sim-bridge                                  # sends to a ground station on udp 14550
  rov-mav sim-bridge --out udpout:127.0.0.1:14550 --listen tcpin:0.0.0.0:5760
  rov-mav sim-bridge --listen udpin:127.0.0.1:14551 --speedup 10 --environment square
  rov-mav sim-bridge --listen udpin:127.0.0.1:14550 --listen udpin:127.0.0.1:14551 --signing-passphrase TEXT
  rov-mav sim-bridge --listen udpin:127.0.0.1:14551 --link-faults loss=0.2,delay=50ms,jitter=10ms --seed 3
  rov-mav sim-bridge --listen udpin:127.0.0.1:14551 --vehicle-faults thruster=3:dead@60s,leak@90s \
      --param FS_LEAK_ENABLE=2

Stop with Ctrl-C or SIGTERM; the achieved speedup, the loop's timing and the count of messages received (and of
any that raised an error while being handled: each is also reported on stderr) are printed on exit.
"""


FLOAT32_MAX = 3.4028234663852886e38
MAX_START_DEPTH = 300.0            # m: a Bar30 depth sensor's range
MIN_STEP, MAX_STEP = 1e-4, 0.01    # s: 10 kHz to 100 Hz (ArduSub runs at 400 Hz)


def _origin(text: str) -> tuple[float, float, float]:
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    if len(values) not in (2, 3):
        raise argparse.ArgumentTypeError(f"{text}: expected LAT,LON or LAT,LON,ALT")
    lat, lon, alt = values[0], values[1], values[2] if len(values) == 3 else 0.0
    if not (-90 <= lat <= 90 and -180 <= lon <= 180 and abs(alt) <= 10_000):
        raise argparse.ArgumentTypeError(f"{text}: need -90 <= LAT <= 90, -180 <= LON <= 180, |ALT| <= 10000 m")
    return lat, lon, alt


def _faults(text: str) -> FaultSpec:
    try:
        return load_faults(text)
    except FaultError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _vehicle_faults(text: str) -> VehicleFaults:
    try:
        return load_vehicle_faults(text)
    except VehicleFaultError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _navigation(text: str) -> Navigation:
    try:
        return load_navigation(text)
    except NavigationError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _param(text: str) -> tuple[str, float]:
    """NAME=VALUE with VALUE a finite float32, as MAVLink carries parameters (whether NAME exists is the bridge's
    to say)."""
    name, _, value = text.partition("=")
    try:
        number = float(value)
    except ValueError:
        number = None
    if number is None or not name.strip():
        raise argparse.ArgumentTypeError(f"{text}: expected NAME=VALUE")
    if not abs(number) <= FLOAT32_MAX:
        raise argparse.ArgumentTypeError(f"{text}: the value must be a finite 32-bit float (|VALUE| <= 3.4e38)")
    return name.strip().upper(), number


def configure(p: argparse.ArgumentParser) -> None:
    p.description, p.epilog, p.formatter_class = DESCRIPTION, EPILOG, argparse.RawDescriptionHelpFormatter
    p.add_argument("--out", action="append", default=[], type=endpoint(("udpout",)), metavar="udpout:HOST:PORT",
                   help=f"send to a ground station at HOST:PORT, as a vehicle does (repeatable; default "
                        f"{DEFAULT_OUT} when no --out or --listen is given)")
    p.add_argument("--listen", action="append", default=[], type=endpoint(("udpin", "tcpin")),
                   metavar="udpin|tcpin:HOST:PORT",
                   help="wait on HOST:PORT and answer whoever writes (udpin: the last sender; tcpin: every "
                        "connected client); repeatable, several links at once")
    p.add_argument("--speedup", type=speedup, default=1.0, metavar="N",
                   help="simulated time runs N times faster than the wall clock (default 1: real time)")
    p.add_argument("--environment", type=mission_file, metavar="NAME|FILE",
                   help="disturbance, current, sensor noise, the bottom and ice: the environment: block of a shipped "
                        "mission (by name) or of a mission file, or a file holding just that block (default: still "
                        "water, no noise, no bottom)")
    p.add_argument("--vehicle", type=vehicle_file, metavar="NAME|FILE",
                   help=f"the simulated vehicle: {VEHICLE_HELP} (default: bluerov2_heavy)")
    p.add_argument("--firmware", choices=FIRMWARES, default=DEFAULT_FIRMWARE,
                   help="ArduSub version whose parameter names to use: 4.7 (MAV_GCS_SYSID, MAV_SYSID, MAVn_* "
                        "stream rates) or 4.5 (SYSID_MYGCS, SYSID_THISMAV, SRn_*); default %(default)s")
    p.add_argument("--origin", type=_origin, default=DEFAULT_ORIGIN, metavar="LAT,LON[,ALT]",
                   help="where local position (0, 0, 0) is on the globe, surface altitude in m "
                        "(default %s,%s,%s)" % DEFAULT_ORIGIN)
    p.add_argument("--start-depth", type=number(0.0, MAX_START_DEPTH), default=0.0, metavar="M",
                   help="depth in m at boot (default 0: at the surface; the model has no free surface)")
    p.add_argument("--step", type=number(MIN_STEP, MAX_STEP), default=DEFAULT_STEP, metavar="S",
                   help="fixed physics and main-loop step in simulated seconds (default %(default)s: 400 Hz)")
    p.add_argument("--seed", type=seed, default=0, help="seed of the sensor noise and the link faults (default 0)")
    _add_fault_options(p)
    p.add_argument("--log-dir", metavar="DIR",
                   help="write the vehicle's own DataFlash logs (.BIN, as ArduSub's logs/ folder: DIR/00000001.BIN "
                        "and on, LASTLOG.TXT; one file from each arming with LOG_DISARMED 0, the default, or from "
                        "each boot with LOG_DISARMED 1; LOG_FILE_DSRMROT 1 starts a new one after each disarm). "
                        "`rov-mav analyze FILE.BIN` reviews one. Default: none written")
    p.add_argument("--param", action="append", default=[], type=_param, metavar="NAME=VALUE",
                   help="start with parameter NAME set to VALUE, e.g. FS_PILOT_INPUT=0 (repeatable)")
    add_signing_options(p, "start with this key, as ArduSub with a key stored: every link signs what it sends and "
                           "drops frames not signed with the key, except RADIO_STATUS/RADIO and except on the first "
                           "link (the first --out, else the first --listen: ArduPilot's channel 0, USB, taken as "
                           "secure). Without a key, a ground station can "
                           "set one with SETUP_SIGNING (MAVProxy: `signing setup PASSPHRASE`), refused while armed; "
                           "an all-zero key turns signing off.")
    p.set_defaults(func=run)


def _add_fault_options(p: argparse.ArgumentParser) -> None:
    """What degrades on purpose: the links, the vehicle, its navigation."""
    p.add_argument("--link-faults", type=_faults, metavar="SPEC|FILE",
                   help="degrade the links on purpose, both directions, in vehicle time: comma-separated "
                        "loss=P (0..1 or %%), delay=T, jitter=T (uniform +-T; order kept), dup=P, reorder=P "
                        "(a message arrives after the next one), cut=LENGTH@START (nothing passes), "
                        "drop=MESSAGE[@START] (that type never arrives; repeatable), link=N (only endpoint N, "
                        "counted from 0, --out ones first; default all), times with ms or s, e.g. "
                        "loss=0.2,delay=50ms,cut=30s@20s; or a YAML file with the same keys")
    p.add_argument("--vehicle-faults", type=_vehicle_faults, metavar="SPEC|FILE",
                   help="break the vehicle on purpose, at vehicle times since the start (they run on through "
                        "reboots): comma-separated thruster=N:dead@T, thruster=N:stuck=PWM@T (1100..1900 us), "
                        "thruster=N:weak=K@T (0 < K < 1), thruster=N:reversed@T (N = motor 1..8), reboot@T "
                        "(repeatable), leak@T, battery=RATE[@T] (extra sag in V/s, e.g. 0.05V/s), "
                        "navigation-lost@T[+D] (for D, or for good), navigation-reset=N/E@T (the estimate moved N m "
                        "north, E m east: a DVL's set position), depth-sensor@T, times with their unit, e.g. "
                        "thruster=3:dead@60s,reboot@90s; or a YAML file holding vehicle_faults: (that text or a "
                        "list of items). Replaces an --environment file's vehicle_faults")
    p.add_argument("--navigation", type=_navigation, metavar="NAME|FILE",
                   help=f"how the vehicle knows where it is: {', '.join(PRESET_NAMES)} (ideal, the default: the "
                        "plant's state plus the environment's noise, valid from boot; none: attitude and depth "
                        "only, no LOCAL_POSITION_NED; dvl: a DVL A50-class bottom-track velocity, dead reckoning "
                        "that drifts; ugps: Underwater GPS G2-class acoustic fixes, late, noisy with range, with "
                        "outliers and dropouts), fused by an EKF3 stand-in; or a YAML file with a navigation: block "
                        "(preset: and any of imu:, compass:, bar30:, dvl:, ugps: with their parameters). Replaces "
                        "an --environment file's navigation")


def run(args: argparse.Namespace) -> int:
    endpoints = tuple(args.out + args.listen) or (DEFAULT_OUT,)
    environment = load_environment(args.environment) if args.environment else None
    config = BridgeConfig(endpoints=endpoints, speedup=args.speedup, firmware=args.firmware, environment=environment,
                          vehicle_path=args.vehicle, origin=args.origin, start_depth=args.start_depth,
                          step=args.step, seed=args.seed, params=dict(args.param), signing_key=signing_key(args),
                          faults=args.link_faults, vehicle_faults=args.vehicle_faults, navigation=args.navigation,
                          log_dir=args.log_dir)
    from sim_bridge.server import (
        Bridge,  # the physics stack loads only when a bridge runs
    )

    try:
        bridge = Bridge(config)
    except ValueError as exc:
        print(f"rov-mav sim-bridge: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"rov-mav sim-bridge: error: --log-dir {args.log_dir}: {(exc.strerror or str(exc)).lower()}",
              file=sys.stderr)
        return 2
    try:
        bridge.open()
    except TransportError as exc:
        print(f"rov-mav sim-bridge: error: {exc}", file=sys.stderr)
        return 1
    faults = f", link faults {args.link_faults.describe()}" if args.link_faults is not None else ""
    if bridge.vehicle_faults:
        faults += f", vehicle faults {bridge.vehicle_faults.describe()}"
    if not bridge.navigation.ideal:
        faults += f", navigation {bridge.navigation.describe()}"
    print(f"sim-bridge: ArduSub {args.firmware} ({bridge.vehicle.name}) on {', '.join(endpoints)}, "
          f"speedup {args.speedup:g}{', MAVLink 2 signing on' if bridge.signing.enabled else ''}{faults}", flush=True)
    previous = {sig: signal.signal(sig, lambda *_: bridge.request_stop()) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        bridge.run()
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    s = bridge.pacer.summary(bridge.t)
    print(f"sim-bridge: stopped at t={s['sim_time']:.2f} s after {s['wall_time']:.2f} s wall "
          f"(speedup {s['speedup']:.3f}, {s['slips']} slips); step lateness ms: mean {s['late_mean_ms']:.3f} "
          f"p50 {s['late_p50_ms']:.3f} p99 {s['late_p99_ms']:.3f} max {s['late_max_ms']:.3f}", flush=True)
    print(f"sim-bridge: {bridge.messages_received} messages received ({len(bridge.message_types)} types), "
          f"{bridge.handler_errors} handler errors", flush=True)
    if bridge.boot.reboots:
        print(f"sim-bridge: {bridge.boot.reboots} reboot(s); {bridge.messages_ignored} messages arrived while the "
              "autopilot was off or booting and were ignored", flush=True)
    if rejected := {link.channel: link.rejections.count for link in bridge.links if link.rejections.count}:
        print("sim-bridge: frames dropped for their signature: "
              + ", ".join(f"link {channel}: {n}" for channel, n in rejected.items()), flush=True)
    for link in bridge.links:
        if link.faults is not None:
            print(f"sim-bridge: link {link.channel} faults: {link.faults.describe()}", flush=True)
    return 0
