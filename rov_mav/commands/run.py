"""`rov-mav run`: fly a mission on a vehicle over MAVLink (ArduSub, SITL, or the built-in bridge), safely."""

from __future__ import annotations

import argparse
import json
import socket
import sys
from pathlib import Path

from rov_mav.commands.arguments import (
    count,
    mavlink_target,
    mission_file,
    number,
    output_file,
    output_folder,
    positive_float,
    seconds,
    speedup,
    sysid,
)
from rov_mav.commands.common import (
    MISSION_HELP,
    add_controller_options,
    add_plan_options,
    add_rerun_option,
    add_signing_options,
    check_rerun_output,
    controller_settings,
    load_mission,
    plan_options,
    report_skipped,
    rerun_sink,
    signing_key,
)
from rov_mav.config import ConfigError
from rov_mav.flight.run.run_options import DEFAULT_MAX_TILT_DEG
from rov_mav.mission.missions import MAX_SPEED

MAX_RATE = 400.0              # Hz: ArduSub's main loop; no telemetry comes faster
MAX_LINK_TIMEOUT = 60.0       # vehicle s: flying blind longer than this is not a setting
MAX_BAUD = 10_000_000
MAX_VELOCITY_BLEND = 50.0     # rad/s: the filter is stepped at the control rate; beyond this it is no filter

DESCRIPTION = """\
Fly MISSION with the backstepping law and its disturbance adaptation, over MAVLink, on a BlueROV2 Heavy running
ArduSub (a real one, ArduSub SITL, or `rov-mav sim-bridge`). Without --target, the built-in simulated vehicle
starts in a child process (at the mission's start depth, in the mission's environment) and the mission is flown
there.

How it drives the thrusters (--output thrusters): SERVO1..8_FUNCTION are saved and switched to RCIN1..8 passthrough
(each confirmed), and 8 PWMs go out with RC_CHANNELS_OVERRIDE at --rate Hz of vehicle time, neutral (1500) first and
last. Passthrough outputs are NOT gated by arming and KEEP their last PWM when the overrides stop, so on every exit
(mission complete, Ctrl-C, SIGTERM, an error, a lost link, a failed arm, a limit crossed) the runner sends neutral on
all 8 channels, releases the overrides, disarms and restores SERVO1..8_FUNCTION, and prints what it did. If the link
is gone it says so: the thrusters then hold their last command on the vehicle. Requests (parameters, commands) are
resent with growing waits, so that a lossy link (30 % each way) does not stop a start or a stop; a step of the stop
the vehicle never confirmed is named, and the exit status is then not 0.

With --output motor-test the outputs stay on their motors and the same PWMs go out as ArduSub's motor test
(MAV_CMD_DO_MOTOR_TEST, 8 commands a tick) after MANUAL and arming, neutral RC overrides held as pilot input.
ArduSub runs no mixer during the test and ends it, disarming, 0.5 s of vehicle time after the last command: if this
process is killed outright (SIGKILL, out of memory, a crash) or the link is cut, the thrusters stop by themselves.
The stop is the same (neutral, release, disarm); a pilot takeover ends the test, so the vehicle disarms and the
pilot arms it again. ArduSub refuses the test for 10 s after an earlier one timed out (the run waits for it).

With --controller ardusub-guided there is no law of ours: SERVO1..8_FUNCTION stay on the motors, the run sets
GUIDED, arms, and streams the reference (lead-in included) as SET_POSITION_TARGET_LOCAL_NED (position, velocity,
yaw) at --guided-rate Hz of vehicle time; neutral RC overrides are held as pilot input (ArduSub's pilot-input
failsafe disarms without it). Its stop leaves GUIDED for MANUAL, then does the same neutral, release and disarm, and
sets back the mode it found.

Before sending anything it watches the link for 3 s of vehicle time and refuses (unless --force) a vehicle that is
not ArduSub on a submarine, is armed, is driven by another station (RC overrides, motor tests, a joystick off
centre) or whose RC input is changing; outputs found on passthrough are taken as abandoned only when none of that
holds. A pilot station whose joystick rests on the GCS sysid (QGroundControl, Cockpit) is made to coexist: the run
takes the GCS role with a sysid of its own (MAV_GCS_SYSID / SYSID_MYGCS set for the run, restored on exit). While
flying, a joystick moved off centre, another station's RC overrides, RC input the run did not send or a mode changed
by someone else hand the vehicle over: neutral, overrides released, SERVO1..8_FUNCTION back to the motors, the GCS
sysid restored, left armed for the pilot (exit status 3). Then ATTITUDE and LOCAL_POSITION_NED must arrive at the
control rate (sent by the vehicle at 80 % of it, arriving at 50 % or more: a 30 % loss is flown through). Safety
while flying: telemetry older than 3 control periods -> neutral until it returns; older than --link-timeout ->
abort. Limits (the mission's `limits:` block, or the flags): depth, tracking error, thrust per thruster.
"""

EPILOG = """\
examples:
  rov-mav run square                                   # the shipped square, built-in simulated vehicle, real time
  rov-mav run square --speedup 10                      # the same, 10x faster than real time
  rov-mav run my_square.yaml --speedup 10              # a mission file (`rov-mav missions`: the shipped ones)
  rov-mav sim-bridge &  rov-mav run --target udp:127.0.0.1:14550 square
  rov-mav run --target tcp:127.0.0.1:5760 square       # ArduSub SITL
  rov-mav run --target udp:0.0.0.0:14550 --dry-run square --log out/dry
  rov-mav run --target udp:0.0.0.0:14550 --signing-passphrase TEXT square   # a vehicle that signs
  rov-mav run survey.plan --speedup 10                 # a QGroundControl plan
  rov-mav run --target udp:127.0.0.1:14550 --mission-from-vehicle  # the mission uploaded to the vehicle

exit status: 0 mission complete and the vehicle left safe; 1 aborted or refused (the reason is printed), or a
safe-stop step not confirmed (named); 2 bad arguments or files;
3 handed over to another station (pilot takeover); 6 a thruster failed and what is left cannot fly the
mission; 7 the vehicle rebooted; 8 the vehicle's own failsafe (a leak, a critical battery, its estimator, its depth
sensor, SURFACE); 128+N stopped by signal N (130 Ctrl-C, 143 SIGTERM).
"""


def configure(p: argparse.ArgumentParser) -> None:
    p.description, p.epilog, p.formatter_class = DESCRIPTION, EPILOG, argparse.RawDescriptionHelpFormatter
    p.add_argument("mission", nargs="?", type=mission_file, help=MISSION_HELP)
    p.add_argument("--mission-from-vehicle", action="store_true",
                   help="instead of a file, fly the mission stored on the vehicle (uploaded with QGroundControl or "
                        "MAVProxy): downloaded with the MAVLink mission protocol, read as a plan's items; needs "
                        "--target")
    add_plan_options(p)
    p.add_argument("--target", type=mavlink_target, metavar="CONN",
                   help="pymavlink connection: udp:HOST:PORT (listen; a vehicle sends to 14550), udpout:HOST:PORT, "
                        "tcp:HOST:PORT (ArduSub SITL: tcp:127.0.0.1:5760), or a serial device (see --baud); "
                        "default: start the built-in simulated vehicle in a child process")
    add_controller_options(p)
    p.add_argument("--rate", type=number(1.0, MAX_RATE), default=50.0, metavar="HZ",
                   help="control rate in Hz of vehicle time, 1 to 400: telemetry asked for and overrides sent "
                        "(default 50)")
    p.add_argument("--guided-rate", type=number(0.5, MAX_RATE), default=10.0, metavar="HZ",
                   help="--controller ardusub-guided: SET_POSITION_TARGET_LOCAL_NED per second of vehicle time, 0.5 "
                        "to 400 (default 10)")
    p.add_argument("--output", choices=["thrusters", "motor-test"], default="thrusters",
                   help="how the per-thruster PWMs reach the vehicle: thrusters = RC overrides with SERVO1..8 on RCIN "
                        "passthrough (default); motor-test = ArduSub's motor test (MAV_CMD_DO_MOTOR_TEST), outputs "
                        "left on their motors, stopped and disarmed by ArduSub 0.5 s after our last command, so a "
                        "run killed outright leaves the thrusters stopped (8 commands per tick: a fast link)")
    p.add_argument("--dry-run", action="store_true",
                   help="connect and compute everything (logged), but change no parameter, arm nothing and send no "
                        "override; limit crossings are reported, not acted on")
    p.add_argument("--force", action="store_true",
                   help="take over a vehicle that is already armed or that another station is driving")
    p.add_argument("--metrics", type=output_file, metavar="FILE",
                   help="write the tracking metrics JSON (as `simulate` does) here")
    p.add_argument("--log", type=output_folder, metavar="DIR",
                   help="write ticks.csv (state, reference, commands, controller internals), events.csv, the "
                        "raw MAVLink traffic (mavlink.tlog) and run.json to DIR (review it with `rov-mav analyze DIR`)")
    _add_limit_options(p)
    _add_link_options(p)
    _add_loop_options(p)
    _add_builtin_options(p)
    add_signing_options(p, "with a key, the run signs everything it sends and ignores (counts, and reports once) "
                           "whatever arrives unsigned or signed with another key; a vehicle that does not sign with "
                           "the key is refused. The built-in vehicle gets the same key.")
    add_rerun_option(p)
    p.set_defaults(func=main)


def _add_limit_options(p: argparse.ArgumentParser) -> None:
    limits = p.add_argument_group("limits (default: the mission's `limits:` block)")
    limits.add_argument("--max-depth", type=positive_float, metavar="M", help="abort below this depth")
    limits.add_argument("--max-tracking-error", type=positive_float, metavar="M",
                        help="abort when the position error exceeds this")
    limits.add_argument("--max-thrust", type=positive_float, metavar="N",
                        help="cap each thruster's command at this thrust, and abort if the vehicle reports more")
    limits.add_argument("--max-tilt", type=number(0.0, 89.0, low_open=True), metavar="DEG",
                        help=f"abort when the roll or pitch exceeds this many degrees (default: the mission's "
                             f"max_tilt, else {DEFAULT_MAX_TILT_DEG:g})")


def _add_link_options(p: argparse.ArgumentParser) -> None:
    link = p.add_argument_group("link")
    link.add_argument("--sysid", type=sysid, metavar="ID",
                      help="our MAVLink system id, 1 to 255 (default: the vehicle's MAV_GCS_SYSID / SYSID_MYGCS, "
                           "usually 255; another one, or a pilot's joystick on that sysid, makes the run take the GCS "
                           "role with its own sysid for the run)")
    link.add_argument("--baud", type=count(MAX_BAUD), default=115200, help="serial baud rate (default 115200)")
    link.add_argument("--heartbeat-timeout", type=seconds, default=15.0, metavar="S",
                      help="wall seconds to wait for the vehicle's heartbeat (default 15)")
    link.add_argument("--position-timeout", type=seconds, default=90.0, metavar="S",
                      help="wall seconds to wait for LOCAL_POSITION_NED (default 90)")
    link.add_argument("--link-timeout", type=number(0.0, MAX_LINK_TIMEOUT, low_open=True), default=2.0,
                      metavar="S",
                      help="vehicle seconds without telemetry before the run aborts as a lost link (default 2)")


def _add_loop_options(p: argparse.ArgumentParser) -> None:
    """How the loop flies: the lead-in, the estimate's blend, PWM rounding, prediction, pretension, the thruster
    check, the estimator, real-time scheduling."""
    p.add_argument("--approach-speed", type=number(0.0, MAX_SPEED, low_open=True), default=0.2, metavar="M/S",
                   help="speed of the lead-in from where the vehicle is to the mission's start (default 0.2)")
    p.add_argument("--velocity-blend", type=number(0.0, MAX_VELOCITY_BLEND), default=0.2, metavar="RAD_S",
                   help="bandwidth of the blend of the reported position and velocity the law flies on: motion the "
                        "velocity shows is taken at once, the position's corrections (an acoustic fix's, every "
                        "quarter second) below this, and a steady disagreement of the two is learnt; 0 uses both as "
                        "reported (default 0.2)")
    p.add_argument("--pwm-rounding", choices=["diffuse", "nearest"], default="diffuse",
                   help="whole-microsecond PWMs and thruster dead bands: carry what a tick's PWM could not give to the "
                        "next tick, so thrust averages to what was asked (diffuse, default), or round each tick alone")
    p.add_argument("--predict", choices=["on", "off"], default="on",
                   help="act on the state predicted to the instant the command reaches the thrusters (on, default: "
                        "the telemetry's age plus the link's round trip, measured with TIMESYNC, through the law's "
                        "model and the commands already sent), or on the state as it arrives (off)")
    p.add_argument("--pretension", choices=["on", "off"], default="on",
                   help="add thrust patterns with no net wrench so that every thruster works outside its dead band "
                        "(on, default: small moments without thrusters switching on and off), or not")
    p.add_argument("--thruster-check", choices=["on", "off"], default="on",
                   help="watch every thruster for doing what it is told, from the vehicle's motion (on, default: a "
                        "1 N pattern of thrusts with no net wrench, 2 s period, keeps each one's commands moving; a "
                        "dead, stuck, weak or reversed thruster is named, the allocation re-solved around it, and the "
                        "run stops, exit 6, if what is left cannot fly the mission), or not (off)")
    p.add_argument("--estimator", choices=["vehicle", "model"], default="vehicle",
                   help="the position and velocity the law flies on: the vehicle's own estimate (vehicle, default: "
                        "ArduSub's EKF, through LOCAL_POSITION_NED), or the run's own (model): a Kalman filter that "
                        "predicts with the vehicle model under the thrust the run commands and fuses the navigation "
                        "sources' messages on the link (GPS_INPUT fixes, VISION_POSITION_DELTA DVL velocities) at "
                        "their own time, the vehicle's attitude and depth, and its position while no source speaks")
    p.add_argument("--realtime", action="store_true",
                   help="ask the operating system for real-time scheduling (SCHED_FIFO) and locked memory, so that a "
                        "busy computer does not stall the loop; says in one line what was refused (it needs root or "
                        "CAP_SYS_NICE and CAP_IPC_LOCK) and flies on at normal priority")


def _add_builtin_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--speedup", type=speedup, default=1.0, metavar="N",
                   help="built-in vehicle only: run it N times faster than real time (default 1)")
    p.add_argument("--navigation", type=_navigation, metavar="NAME|FILE",
                   help="built-in vehicle only: how it knows where it is, as `rov-mav sim-bridge --navigation` "
                        "(ideal, none, dvl, ugps, dvl+ugps, or a YAML file with a navigation: block; replaces the "
                        "mission's environment: navigation; default: that, else ideal)")
    p.add_argument("--vehicle-faults", type=_vehicle_faults, metavar="SPEC|FILE",
                   help="built-in vehicle only: make it fail on purpose, in vehicle s since it started (as "
                        "`rov-mav sim-bridge --vehicle-faults`; replaces the mission's environment: vehicle_faults): "
                        "thruster=N:dead|stuck=PWM|weak=K|reversed@T, reboot@T, leak@T, battery=RATE[@T] (V/s), "
                        "navigation-lost@T[+D], navigation-reset=N/E@T (m), depth-sensor@T, comma-separated, e.g. "
                        "thruster=3:dead@60s")


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _vehicle_faults(text: str):
    from rov_mav.model.vehicle_faults import VehicleFaultError, load_vehicle_faults

    try:
        return load_vehicle_faults(text)
    except VehicleFaultError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _navigation(text: str):
    from rov_mav.model.navigation import NavigationError, load_navigation

    try:
        return load_navigation(text)
    except NavigationError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


class _BuiltIn:
    """The built-in vehicle in a child process (`sim_bridge.process`: never sharing this interpreter's lock with the
    loop), its home at the mission's origin when it has one, loading while this process gets ready."""

    def __init__(self, mission, speedup: float, key: bytes | None, vehicle_faults=None, navigation=None):
        from sim_bridge.config import DEFAULT_ORIGIN, BridgeConfig
        from sim_bridge.process import VehicleProcess

        self.port, self.speedup = _free_udp_port(), speedup
        origin = (*mission.origin, 0.0) if mission.origin else DEFAULT_ORIGIN
        self.process = VehicleProcess(BridgeConfig(
            endpoints=(f"udpin:127.0.0.1:{self.port}",), speedup=speedup, environment=mission.environment,
            start_depth=float(mission.start_pose[2]), origin=origin, signing_key=key, vehicle_faults=vehicle_faults,
            navigation=navigation))
        self.process.launch()

    @property
    def target(self) -> str:
        return f"udpout:127.0.0.1:{self.port}"

    def start(self) -> None:
        """Its clock starts (LinkError, one line, if it cannot)."""
        from rov_mav.flight.session.link import LinkError
        from sim_bridge.transport.link import TransportError

        try:
            self.process.start()
        except TransportError as exc:
            raise LinkError(f"the built-in vehicle could not start: {exc}") from None
        print(f"built-in vehicle: simulated BlueROV2 Heavy (ArduSub {self.process.firmware}) on udp port "
              f"{self.port}, speedup {self.speedup:g}", flush=True)

    def stop(self) -> None:
        self.process.stop()


def _default_recording(mission) -> Path:
    """Where a run records for Rerun without --rerun and without a display."""
    return Path(f"out/run-{mission.name}/run.rrd")


def _refusal(args: argparse.Namespace) -> str | None:
    """Why these options cannot make a run, in one line; None when they can."""
    from rov_mav.flight.run.guided import KIND as GUIDED_KIND
    from rov_mav.flight.run.run_options import THRUSTERS, VEHICLE

    if (args.mission is None) != args.mission_from_vehicle or (args.mission_from_vehicle and args.target is None):
        return ("give a mission (a shipped mission's name or a file), or --mission-from-vehicle with --target (the "
                "built-in vehicle starts with no mission)")
    for option, value in (("--vehicle-faults", args.vehicle_faults), ("--navigation", args.navigation)):
        if args.target is not None and value is not None:
            return f"{option} applies to the built-in vehicle only (no --target)"
    if args.target is not None and args.speedup != 1.0:
        return "--speedup applies to the built-in vehicle only (no --target)"
    if args.controller == GUIDED_KIND and args.estimator != VEHICLE:
        return (f"--estimator {args.estimator} is the law's; --controller {GUIDED_KIND} flies on ArduSub's own "
                "estimate")
    if args.controller == GUIDED_KIND and args.output != THRUSTERS:
        return f"--output {args.output} carries a law's PWMs; --controller {GUIDED_KIND} flies on ArduSub's own mixer"
    return None


def _choices(args: argparse.Namespace):
    """The run's choices (`flight.run.assembly.Choices`) from the command line; ConfigError for a bad file."""
    from rov_mav.flight.run.assembly import Choices, LimitFlags, run_limits
    from rov_mav.flight.run.guided import KIND as GUIDED_KIND
    from rov_mav.flight.run.run_options import Limits, RunOptions
    from rov_mav.model.vehicle import load_flown_vehicle

    mission = None if args.mission_from_vehicle else load_mission(args)
    if mission is not None and args.controller == GUIDED_KIND and any(
            seg.terrain is not None and seg.terrain[0] == "standoff" for seg in mission.segments):
        raise ConfigError(f"{mission.source}: a standoff below the ice: --controller {GUIDED_KIND} has none (ArduSub's "
                          "terrain frames are heights above the bottom); fly it with a law of ours")
    flags = LimitFlags(args.max_depth, args.max_tracking_error, args.max_thrust, args.max_tilt)
    limits = Limits() if mission is None else run_limits(mission, flags)   # set once the vehicle's is downloaded
    if mission is not None:
        check_rerun_output(args, _default_recording(mission))
    options = RunOptions(rate=args.rate, dry_run=args.dry_run, force=args.force, sysid=args.sysid,
                         heartbeat_timeout=args.heartbeat_timeout, position_timeout=args.position_timeout,
                         link_timeout=args.link_timeout, approach_speed=args.approach_speed,
                         velocity_blend=args.velocity_blend, output=args.output, predict=args.predict == "on",
                         thruster_check=args.thruster_check == "on", estimator=args.estimator,
                         limits=limits)
    return Choices(mission=mission, model=load_flown_vehicle(args.vehicle),
                   settings=None if args.controller == GUIDED_KIND else controller_settings(args),
                   options=options, limit_flags=flags, target=args.target, sysid=args.sysid or 255, baud=args.baud,
                   speedup=args.speedup, key=signing_key(args), guided_rate=args.guided_rate, log=args.log,
                   diffuse=args.pwm_rounding == "diffuse", pretension=args.pretension == "on")


def _flight(args: argparse.Namespace, choices):
    """The flight of `choices`, with what only the command line can give it: the built-in vehicle, the recording,
    the mission downloaded from the vehicle."""
    from rov_mav.flight.run.assembly import Flight
    from rov_mav.flight.session.vehicle_mission import vehicle_mission

    def launch(mission):
        vehicle = _BuiltIn(mission, args.speedup, choices.key, args.vehicle_faults, args.navigation)
        return vehicle, vehicle.target

    def recording(mission):
        return rerun_sink(args, choices.model, mission, _default_recording(mission))

    def from_vehicle(session):
        """Connect and download the vehicle's mission (nothing on the vehicle changes)."""
        vehicle = session.connect(args.heartbeat_timeout)
        mission = vehicle_mission(session, plan_options(args))
        report_skipped(mission)
        print(f"mission downloaded from vehicle {vehicle.sysid}: {len(mission.segments)} segments, "
              f"{mission.duration:.1f} s", flush=True)
        check_rerun_output(args, _default_recording(mission))
        return mission

    return Flight(choices, launch, recording, from_vehicle)


def main(args: argparse.Namespace) -> int:
    # Imported here, when the command runs, so that `rov-mav --help` and the other commands start fast.
    from rov_mav.flight.session.link import LinkError

    if why := _refusal(args):
        print(f"rov-mav run: error: {why}", file=sys.stderr)
        return 2
    choices = _choices(args)
    if args.realtime:
        from rov_mav.flight.run.realtime import ask_realtime
        granted, line = ask_realtime()
        print(line, file=sys.stdout if granted else sys.stderr, flush=True)
    flight = _flight(args, choices)
    try:
        flight.open()
    except (LinkError, ConfigError) as exc:
        flight.close()
        if isinstance(exc, ConfigError):
            raise
        print(f"rov-mav run: error: {exc}", file=sys.stderr)
        return 1
    try:   # whatever fails from here on, the link and the built-in vehicle are closed
        result = flight.fly()
    finally:
        flight.close()
    metrics = flight.metrics(result)
    if args.metrics:
        path = Path(args.metrics)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(metrics, indent=2) + "\n")
    for line in _report(args, flight, result, metrics):
        print(line, flush=True)
    return result.code


def _terrain_line(terrain: dict) -> str:
    """The altitude and standoff legs' line: the height held (sounder, truth), strikes, cross-track, speed."""
    cm = lambda key: f"{terrain[key] * 100:.1f} cm"      # noqa: E731
    parts = [f"height error RMS {cm('rms_height_error_sounder_m')} by the sounder"]
    if "rms_height_error_true_m" in terrain:
        parts[0] += f", {cm('rms_height_error_true_m')} (max {cm('max_height_error_true_m')}) from the true surface"
    parts.append(f"{terrain['strikes']} strike(s) under 0.3 m")
    if "rms_cross_track_m" in terrain:
        truth = f" ({cm('rms_cross_track_true_m')} truly)" if "rms_cross_track_true_m" in terrain else ""
        parts.append(f"cross-track RMS {cm('rms_cross_track_m')}{truth}; speed along the line "
                     f"{terrain['rms_speed_error_m_s'] * 100:.1f} cm/s RMS off the plan")
    return "  terrain legs: " + "; ".join(parts)


def _report(args: argparse.Namespace, flight, result, metrics: dict) -> list[str]:
    """What the terminal shows after the run: how it ended, the tracking, the loop, the delays, the recording."""
    loop, cm = metrics["loop"], lambda key: f"{metrics[key] * 100:.2f} cm"
    status = ("completed" if result.code == 0 else f"completed, exit {result.code}: {result.reason}") \
        if result.completed else f"NOT completed ({result.reason})"
    lines = [f"{flight.mission.name} / {flight.choices.kind}{' (dry run)' if args.dry_run else ''}: {status}, "
             f"{metrics['duration_s']:.1f} s of mission flown"]
    if result.t.size:
        truth = f"; against the truth (SIM_STATE) RMS {cm('rms_position_error_truth_m')}, max " \
            f"{cm('max_position_error_truth_m')}" if "rms_position_error_truth_m" in metrics else ""
        lines.append(f"  position error RMS {cm('rms_position_error_m')} (steady {cm('rms_position_error_steady_m')}, "
                     f"max {cm('max_position_error_m')}); attitude RMS {metrics['rms_attitude_error_rad']:.4f} rad"
                     + truth)
        if "rms_estimate_error_truth_m" in metrics:
            own = f"; the vehicle's own estimate {cm('rms_vehicle_estimate_error_truth_m')}" \
                if args.estimator != "vehicle" else ""
            lines.append(f"  the position flown on ({args.estimator}'s estimate) is "
                         f"{cm('rms_estimate_error_truth_m')} RMS from the truth" + own)
    if metrics.get("terrain"):
        lines.append(_terrain_line(metrics["terrain"]))
    lines.append(f"  loop: {loop['ticks']} ticks at {loop['control_rate_hz']:.1f} Hz of vehicle time; telemetry-in "
                 f"to command-out p50 {loop['latency_p50_ms']:.2f} ms, p99 {loop['latency_p99_ms']:.2f} ms; thrusters "
                 f"moved {loop['pwm_activity_us_per_s']:.0f} us/s each (mean sum |dPWM| per second)")
    predicted = f"{loop['horizon_p50_ms']:.1f} ms ahead (p50; p99 {loop['horizon_p99_ms']:.1f} ms)" \
        if args.predict == "on" else "not at all (--predict off)"
    stalls = f"; this process stalled {loop['stalls']} time(s)" if loop["stalls"] else ""
    lines.append(f"  delays: round trip {loop['round_trip_ms']:.1f} ms (TIMESYNC); state predicted {predicted}{stalls}")
    lines.append(f"  rerun: {flight.rerun_target.describe()}")
    if flight.rerun is not None:
        lines.append(f"  {flight.rerun.stats.describe(1.0 / args.rate)}")
    return lines
