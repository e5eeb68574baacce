"""The bridge: the emulated ArduSub, its physics and its MAVLink links in one paced loop.

Each step of h simulated seconds: ArduSub's main loop (RC input, failsafes) -> servo outputs -> physics (with the
thruster faults) -> the navigation estimate -> the telemetry due on each link. Between steps the loop reads the
links and sleeps until the next step is due on the wall clock (`Pacer`). Run it blocking (`run()`, the CLI) or in a
background thread (`start()` / `stop()`).
Vehicle faults (`sim_bridge.hardware.vehicle_faults`) run on `t`, the vehicle's clock since the bridge started; the
autopilot
runs on `uptime`, its time since boot, which a reboot (`reboot@T`, MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN) restarts
(`sim_bridge.hardware.boot`): from the power loss the autopilot sends nothing, ignores what arrives, drives no thruster
and
its TCP clients are disconnected (as a restarting SITL's); at its start a fresh ArduSub (disarmed, MANUAL, no
overrides, RC input and failsafes as at boot, no GCS seen, the stored parameters, no SET_MESSAGE_INTERVAL), a fresh
EKF and battery monitor (mAh counted from 0), the stored mission, each link's sequence restarting under the stored
sysid; the main loop then sends INFO "ArduPilot Ready".
Every message received goes through ArduPilot's routing first (`sim_bridge.gcs.routing`, as
`GCS_MAVLINK::packetReceived`
calls `MAVLink_routing::check_and_forward`): forwarded unchanged to the links it belongs on, and handled here only if
it is for this vehicle and, with MAV_OPTIONS bit 0, from a GCS sysid (`GCS_MAVLINK::accept_packet`).
An exception while handling one received message is contained: counted in `handler_errors`, reported in one stderr
line, and the loop goes on (the fuzz test requires the count to stay 0: this is the last net, not the fix).
"""

from __future__ import annotations

import math
import select
import sys
import threading
import time

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from rov_mav.model.navigation import PRESETS as NAVIGATION_PRESETS
from rov_mav.model.plant import Plant
from rov_mav.model.thrusters import thruster_curve
from rov_mav.model.vehicle import load_flown_vehicle
from sim_bridge.hardware import boot
from sim_bridge.gcs import telemetry
from sim_bridge.autopilot.ardusub import MAV_SEVERITY_INFO, ArduSub
from sim_bridge.hardware.battery import Battery
from sim_bridge.config import BridgeConfig
from sim_bridge.navigation.avionics import Avionics
from sim_bridge.transport.faults import LinkFaults
from sim_bridge.transport.link import Link, open_links
from sim_bridge.gcs.missions import MissionProtocol
from sim_bridge.onboard_log.logger import OnboardLog
from sim_bridge.transport.pacing import Pacer
from sim_bridge.autopilot.params import BUILT_IN_FRAME, INT8, NO_FORWARD, Params, stored_value
from sim_bridge.gcs.routing import Router
from sim_bridge.hardware.physics import Harness, Physics
from sim_bridge.gcs.protocol import Protocol
from sim_bridge.gcs.schedule import GROUP_OF, STREAMS_4_5, Scheduler
from sim_bridge.navigation.sensors import Sensors
from sim_bridge.navigation.source_messages import source_messages
from sim_bridge.navigation.attached import attached_sensors
from sim_bridge.modes.terrain import DOWN as RANGEFINDER_DOWN, MAVLINK_TYPE as MAVLINK_RANGEFINDER
from sim_bridge.gcs.signing import VehicleSigning
from sim_bridge.hardware.vehicle_faults import RebootSchedule, resolve

MAX_IDLE = 0.05                                   # s: longest sleep between checks for a stop request
SENSOR_PERIOD = 0.02                              # s: the failsafes' sensors are read at 50 Hz


class Bridge:
    """A simulated BlueROV2 Heavy running ArduSub, reachable over MAVLink."""

    def __init__(self, config: BridgeConfig = BridgeConfig()):
        if config.speedup <= 0:
            raise ValueError("speedup must be positive")
        self.config = config
        frame = config.params.get("FRAME_CONFIG", BUILT_IN_FRAME)
        self.params = Params(config.firmware,
                             int(stored_value(frame, INT8)) if math.isfinite(frame) else BUILT_IN_FRAME)
        self.navigation = config.navigation or getattr(config.environment, "navigation", None) or \
            NAVIGATION_PRESETS["ideal"]
        # the sensors beyond the navigation suite (an echo sounder): a vehicle carrying a down-looking one was set up
        # for it as BlueOS's Ping service asks, RNGFND1_TYPE 10 (MAVLink), unless told otherwise
        self.attached = attached_sensors(self.navigation, config.seed, config.environment)
        if any(getattr(sensor, "orientation", None) == RANGEFINDER_DOWN for sensor in self.attached):
            self.params.set("RNGFND1_TYPE", MAVLINK_RANGEFINDER)
        for name, value in {**config.params, "SIM_SPEEDUP": config.speedup}.items():
            if name not in self.params:
                raise ValueError(f"unknown parameter {name}")
            if self.params.set(name, value) is None:
                raise ValueError(f"parameter {name}: {value:g} is not a finite 32-bit float")
        faults = config.faults
        if faults is not None and faults.link is not None and faults.link >= len(config.endpoints):
            raise ValueError(f"link faults: link={faults.link}, but the bridge has {len(config.endpoints)} link(s) "
                             f"(0 to {len(config.endpoints) - 1})")
        if not 1 <= self.params.sysid <= 255:
            raise ValueError(f"parameter {self.params.names.sysid}: the vehicle's sysid must be 1 to 255")
        self.vehicle = load_flown_vehicle(config.vehicle_path)
        self.vehicle_faults = resolve(config.vehicle_faults, config.environment)
        self.power_cuts = RebootSchedule(self.vehicle_faults)
        plant = Plant(self.vehicle, config.environment, eta0=np.array([0, 0, config.start_depth, 0, 0, 0.0]),
                      seed=config.seed)
        Plant(self.vehicle).step(np.zeros(6), config.step)   # load the compiled model now, not in a paced step
        battery = Battery(self.params["SIM_BATT_VOLTAGE"], self.params["SIM_BATT_CAP_AH"])
        self.harness = Harness([int(self.params[f"SERVO{n}_FUNCTION"]) for n in range(1, 17)],
                               len(self.vehicle.thruster_positions))
        self.physics = Physics(self.vehicle, plant, battery, thruster_curve(self.vehicle), config.step,
                               self.vehicle_faults)
        # the navigation's sensors (None: ideal, the plant's state plus the environment's noise, as before)
        self.sensors = None if self.navigation.ideal else Sensors(self.navigation, config.seed, plant.eta, plant.nu)
        self.source_messages = 0                  # GPS_INPUT and VISION_POSITION_DELTA sent
        self._origin_told: set[int] = set()
        self.signing = VehicleSigning(config.signing_key, time.time())
        self.missions = MissionProtocol(lambda: config.origin)
        self.boot = boot.Boot(config.step)
        self.onboard_log = OnboardLog(config.log_dir) if config.log_dir else None
        self.links: list[Link] = []
        self.schedulers: list[Scheduler] = []
        self.steps = 0
        self.messages_received = 0
        self.messages_ignored = 0                 # arrived while the autopilot was off or booting
        self.message_types: set[str] = set()      # of the dialect's types received (unknown ids not counted)
        self.handler_errors = 0
        self._step_us = round(config.step * 1e6)
        self.unix_start = time.time()
        self._start_firmware()
        self.sub.initialised = True               # the bridge starts with its autopilot booted
        self.servo = self.sub.servo_outputs()
        self.measured = plant.measured() if self.sensors is None else (plant.eta, plant.nu)   # the sensors' view
        self.estimate = self._navigate()          # the autopilot's view of them (its EKF's)
        self.pacer: Pacer | None = None
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None
        self.error: BaseException | None = None

    # -- lifecycle -------------------------------------------------------------------------------------------

    def open(self) -> None:
        """Open every link (TransportError, one line, if one cannot be opened)."""
        self.links = open_links(list(self.config.endpoints), self.sub.sysid)
        self.signing.attach(self.links)
        self.signing.on_change = lambda text: print(f"sim-bridge: {text}", flush=True)
        faults = self.config.faults
        for link in self.links:
            link.rejections.on_first = lambda rejected, link=link: print(
                f"sim-bridge: link {link.channel} ({link.spec}): ignoring MAVLink not signed with the key (the "
                f"first: {rejected.describe()}); counted, not reported again", file=sys.stderr, flush=True)
            if faults is not None and faults.applies_to(link.channel):
                link.degrade(LinkFaults.create(faults, self.config.seed, link.channel), lambda: self.t)
        self._start_streams()

    def close(self) -> None:
        for link in self.links:
            link.close()
        if self.onboard_log is not None:
            self.onboard_log.close()

    def run(self) -> None:
        """Run until `request_stop()` (blocking; e.g. from a signal handler), opening the links if not yet open."""
        if not self.links:
            self.open()
        try:
            self._loop()
        finally:
            self.close()

    def start(self) -> None:
        """Open the links and run in a background thread."""
        self.open()
        self._thread = threading.Thread(target=self._run_thread, name="sim-bridge", daemon=True)
        self._thread.start()

    def _run_thread(self) -> None:
        try:
            self._loop()
        except BaseException as exc:          # kept for stop() to raise in the owner's thread
            self.error = exc

    def request_stop(self) -> None:
        self._stop.set()

    def stop(self) -> None:
        """Stop the background thread and close the links; raises what the thread died of, if it did."""
        self.request_stop()
        if self._thread is not None:
            self._thread.join()
            self._thread = None
        self.close()
        if self.error is not None:
            raise self.error

    # -- state -----------------------------------------------------------------------------------------------

    @property
    def t(self) -> float:
        """Simulated time since the bridge started (the vehicle faults' clock), s."""
        return self.steps * self.physics.h

    @property
    def uptime(self) -> float:
        """The autopilot's time since boot, s (negative while it is off)."""
        return self.boot.uptime(self.steps)

    def truth(self) -> tuple[float, np.ndarray, np.ndarray]:
        """(t, eta, nu) of the simulated vehicle, without sensor noise (copies; safe from any thread)."""
        with self._lock:
            plant = self.physics.plant
            return self.t, np.array(plant.eta, dtype=float), np.array(plant.nu, dtype=float)

    def snapshot(self) -> telemetry.Snapshot:
        """What the telemetry reports now (the autopilot's estimate, with the environment's sensor noise)."""
        eta, nu = self.estimate
        battery, sub, avionics, uptime = self.physics.battery, self.sub, self.avionics, self.uptime
        nav = avionics.navigation
        return telemetry.Snapshot(
            t_us=(self.steps - self.boot.start) * self._step_us, eta=np.asarray(eta), nu=np.asarray(nu),
            servo=self.servo, rc_in=sub.rc.radio_in.copy(),
            base_mode=sub.base_mode(), custom_mode=sub.mode, system_status=sub.system_status(),
            throttle=float(sub.pilot_axes()[3]) if sub.armed else 0.0,
            voltage=battery.voltage, current=battery.current, consumed_ah=avionics.consumed_ah(),
            remaining=avionics.remaining(self.params["BATT_CAPACITY"]), origin=self.config.origin,
            water_density=self.vehicle.water_density,
            gravity=self.vehicle.gravity, unix_start=self.unix_start + self.boot.start * self.physics.h,
            firmware=self.params.firmware, mission_count=len(self.missions.items),
            mission_current=sub.auto.mission_current(len(self.missions.items)), safety_on=sub.safety_on,
            initialised=sub.initialised, local_position=not nav.const_pos, ekf_flags=avionics.flags(uptime),
            ekf_variances=avionics.variances(uptime), battery_state=sub.failsafes.battery,
            battery_failsafed=sub.failsafes.battery_failsafed, depth_present=avionics.depth_present,
            depth_healthy=avionics.bar30 is None, bar30_depth=avionics.bar30,
            truth=(self.physics.plant.eta, self.physics.plant.nu), targets=sub.holds.targets() if sub.armed else
            (math.nan,) * 4, truth_heights=self._true_heights(), rangefinder=sub.rangefinder.reading(),
            rangefinder_log=sub.rangefinder.log_row(),
            rangefinder_target=sub.surftrak.target if sub.surftrak.target is not None else -0.01)

    @property
    def _truth_on_link(self) -> bool:
        """The truth (SIM_STATE, and the true heights) is sent with a navigation of sensors, a bottom or ice."""
        environment = self.config.environment
        return self.sensors is not None or getattr(environment, "seafloor", None) is not None or \
            getattr(environment, "ice", None) is not None

    def _true_heights(self) -> tuple[float | None, float | None]:
        """m: the vehicle's origin above the bottom, below the ice, straight up and down (None: no such surface)."""
        eta, environment = self.physics.plant.eta, self.config.environment
        seafloor, ice = getattr(environment, "seafloor", None), getattr(environment, "ice", None)
        return (seafloor.depth_at(eta[0], eta[1]) - eta[2] if seafloor is not None else None,
                eta[2] - ice.depth_at(eta[0], eta[1]) if ice is not None else None)

    def _params_changed(self, t: float) -> None:
        for scheduler in self.schedulers:
            scheduler.refresh(t)

    # -- power and boot ----------------------------------------------------------------------------------------

    def _start_firmware(self) -> None:
        """The firmware starts (at the bridge's start, and after each power loss): a fresh autopilot on the stored
        parameters."""
        if self.boot.reboots:
            self.params.reboot()
        self.sub = ArduSub(self.params, origin=self.config.origin, mission=lambda: self.missions.items)
        self.sub.initialised = False
        plant = self.physics.plant
        self.avionics = Avionics(self.vehicle_faults, self.physics.battery, self.t, self.navigation,
                                 (plant.eta, plant.nu))
        stored = self.missions.items
        self.missions = MissionProtocol(lambda: self.config.origin)
        self.missions.items = stored
        self.protocol = Protocol(self.sub, self.params, self.snapshot, self._params_changed, self.missions,
                                 self.signing)
        if self.onboard_log is not None:
            self.protocol.on_param_set = lambda name, value, t: self.onboard_log.parameter(t, name, value)
        for link in self.links:
            link.restart(self.sub.sysid)
        self.router = Router(self.sub.sysid)      # the routes are learnt again after each boot
        # MAVn_OPTIONS is read at boot (`GCS_MAVLINK::init` makes a NO_FORWARD link private; reboot required)
        self._private = {c for c in range(len(self.config.endpoints)) if self.params.link_options(c) & NO_FORWARD}
        self.schedulers = []
        self._next_sensors = 0.0

    def _start_streams(self) -> None:
        """The main loop's streams: every link's scheduler, from the stored rates."""
        names, uptime = tuple(telemetry.BUILDERS), self.uptime
        groups = {**GROUP_OF, **(STREAMS_4_5 if self.params.firmware == "4.5" else {})}
        if self._truth_on_link:
            groups["SIM_STATE"] = "EXTRA1"                 # the truth, as SITL's
        self.schedulers = [Scheduler(names, lambda g, ch=link.channel: self.params.stream_rate(ch, g), groups)
                           for link in self.links]
        for scheduler in self.schedulers:
            scheduler.refresh(uptime)
        self._origin_told = set()                        # links told the EKF origin since this boot (see _receive)

    def _power_off(self) -> None:
        """The autopilot loses its power: silent, outputs without pulses, TCP clients dropped."""
        self.boot.power_off(self.steps)
        self.sub.texts.clear()
        if self.onboard_log is not None:
            self.onboard_log.reboot()
        self.protocol.reboot_requested = False
        self.servo = np.zeros_like(self.servo)
        for link in self.links:
            link.drop_clients()

    def _navigate(self) -> tuple[np.ndarray, np.ndarray]:
        """The EKF's estimate from the measured state, and whether it has a position for the autopilot."""
        uptime, nav = self.uptime, self.avionics.navigation
        estimate = self.avionics.navigate(self.t, uptime, self.measured)
        self.sub.position_ok_flags = (nav.position_ok(uptime, True), nav.position_ok(uptime, False))
        return estimate

    # -- loop ------------------------------------------------------------------------------------------------

    def _loop(self) -> None:
        self.pacer = Pacer(self.physics.h, self.params["SIM_SPEEDUP"])
        while not self._stop.is_set():
            self._receive()
            speedup = self.params["SIM_SPEEDUP"]
            if speedup > 0:
                self.pacer.set_speedup(speedup, self.t)
            while self.pacer.due(self.t) and not self._stop.is_set():
                self._step()
                self._receive()      # as ArduSub reads its links every main-loop pass, also when catching up
            sockets = [s for link in self.links for s in link.sockets()]
            select.select(sockets, [], [], min(self.pacer.wait(self.t), MAX_IDLE))

    def _step(self) -> None:
        if self.power_cuts.due(self.t):
            self._power_off()
        phase = self.boot.phase(self.steps)
        self.physics.battery.set_sag(self.vehicle_faults.battery_sag(self.t))
        if phase == boot.RUNNING:
            uptime = self.uptime
            fresh = uptime >= self._next_sensors         # read at the fastest failsafe loop's rate (50 Hz)
            if fresh:
                self._next_sensors = uptime + SENSOR_PERIOD
            self.sub.update(uptime, self.estimate, self.avionics.sensors(self.t, uptime) if fresh else None)
            self.servo = self.sub.servo_outputs()
            if self.onboard_log is not None:
                self.onboard_log.step(uptime, self.sub.armed, self.sub.mode, self.snapshot, self.params)
        with self._lock:
            self.physics.step(self.harness.pwm(self.servo), self.t)
            self.steps += 1
        previous, phase = phase, self.boot.phase(self.steps)
        if phase != boot.OFF and previous == boot.OFF:
            self._start_firmware()
        self._sense_attached(phase)
        if self.sensors is None:
            self.measured = self.physics.plant.measured()
            if phase != boot.OFF:
                self.estimate = self._navigate()
        elif self._sense(phase) and phase != boot.OFF:   # the estimate moves only with a sample (50 Hz or more)
            self.estimate = self._navigate()
        if phase == boot.RUNNING and previous != boot.RUNNING:
            self.sub.initialised = True
            self.sub.texts.append((MAV_SEVERITY_INFO, "ArduPilot Ready"))
            self._start_streams()
        self.sub.texts += self.avionics.navigation.texts
        self.avionics.navigation.texts = []
        if phase != boot.RUNNING:
            self._booting()
            return
        self._send_due()

    def _sense(self, phase: int) -> bool:
        """Navigations other than ideal: the sensors sampled from the truth, what reached the autopilot fed to its
        estimator (not while it is off), the sources' own messages sent on every link (their extensions run on the
        companion computer, through the autopilot's reboots)."""
        plant, t = self.physics.plant, self.t
        if t + 1e-9 < self.sensors.next_event:
            return False
        faults = self.vehicle_faults
        items = self.sensors.sample(t, plant.eta, plant.nu, faults.navigation_ok(t), faults.depth_sensor_ok(t))
        if not items:
            return False
        if phase != boot.OFF:
            self.avionics.feed(items)
        heading = float(self.estimate[0][5])
        for msg, source in source_messages(items, self.config.origin, heading):
            self.source_messages += 1
            for link in self.links:
                link.send_as(msg, source)
        return True

    def _sense_attached(self, phase: int) -> None:
        """The sensors beyond the navigation suite: their readings sent on every link from the companion computer,
        which the router also hands the autopilot (not while it is off)."""
        plant, t = self.physics.plant, self.t
        for sensor in self.attached:
            if t + 1e-9 < sensor.next_event:
                continue
            for reading in sensor.sample(t, plant.eta, plant.nu):
                for msg, source in sensor.messages(reading, int(t * 1000)):
                    for link in self.links:
                        link.send_as(msg, source)
                    if phase == boot.RUNNING:
                        self.protocol.handle(msg, -1, None, self.uptime)

    def _send_due(self) -> None:
        """The main loop's output: texts, AUTO's MISSION_ITEM_REACHED, the streams due on each link, the mission
        protocol's requests."""
        uptime = self.uptime
        while self.sub.texts:
            severity, text = self.sub.texts.pop(0)
            if self.onboard_log is not None:
                self.onboard_log.text(uptime, text)
            self._broadcast(telemetry.ENCODER.statustext_encode(severity, text.encode()[:50]))
        for seq in self.sub.auto.reached:              # `GCS::send_mission_item_reached_message`: every link
            self._broadcast(telemetry.ENCODER.mission_item_reached_encode(seq))
        self.sub.auto.reached.clear()
        snap = None
        for link, scheduler in zip(self.links, self.schedulers):
            for msg in self.protocol.queued_params(link.channel, uptime):
                link.send(msg)
            for name in scheduler.due(uptime):
                snap = snap or self.snapshot()
                msg = telemetry.BUILDERS[name](snap)
                if msg is not None:
                    link.send(msg)
                if name == "SIM_STATE":
                    for height in telemetry.sim_heights(snap):
                        link.send(height)
            link.deliver()
        for channel, msg in self.missions.update(uptime):
            for link in self.links:
                if link.channel == channel:
                    link.send(msg)

    def _booting(self) -> None:
        """Off or initialising: only init's delay callback speaks (HEARTBEAT and SYS_STATUS once a second)."""
        self.sub.texts.clear()
        if self.boot.delay_callback_due(self.steps):
            snap = self.snapshot()
            for name in ("HEARTBEAT", "SYS_STATUS"):
                self._broadcast(telemetry.BUILDERS[name](snap))
        for link in self.links:
            link.deliver()

    def _receive(self) -> None:
        uptime, running = self.uptime, self.boot.phase(self.steps) == boot.RUNNING
        channels = [link.channel for link in self.links]
        for link, scheduler in zip(self.links, self.schedulers or [None] * len(self.links)):
            for msg in link.receive():
                self.messages_received += 1
                if running and self.sensors is not None and link.channel not in self._origin_told:
                    # the EKF origin, as ArduSub announces it once set; here once per link when someone is first
                    # heard on it (chosen: on a udpin link nobody listens at boot, and the truth needs the origin)
                    self._origin_told.add(link.channel)
                    link.send(telemetry.gps_global_origin(self.snapshot()))
                if msg.get_msgId() in mavlink.mavlink_map:
                    self.message_types.add(msg.get_type())
                if not running:
                    self.messages_ignored += 1
                    continue
                local, forward = self.router.route(link.channel, msg, channels, self._private)
                for channel in forward:
                    self.links[channel].write(msg.get_msgbuf())
                if not local or not self._accepted(msg):
                    continue
                if self.onboard_log is not None and msg.get_type() == "STATUSTEXT":   # GCS_MAVLINK::handle_statustext
                    sender = msg.get_srcSystem()
                    prefix = "GCS:" if self.params.is_gcs(sender) else f"SRC={sender}/{msg.get_srcComponent()}:"
                    self.onboard_log.text(uptime, prefix + msg.text)
                try:
                    replies = self.protocol.handle(msg, link.channel, scheduler, uptime)
                    for reply, to_all in replies:
                        if to_all:
                            self._broadcast(reply)
                        else:
                            link.send(reply)
                except Exception as exc:          # one bad message must not stop the vehicle
                    self.handler_errors += 1
                    print(f"sim-bridge: error handling {msg.get_type()} from {msg.get_srcSystem()}/"
                          f"{msg.get_srcComponent()} on link {link.channel}: {type(exc).__name__}: {exc}",
                          file=sys.stderr, flush=True)
                if self.protocol.reboot_requested:   # the ACK is out: now the power goes
                    self._power_off()
                    running = False

    def _accepted(self, msg) -> bool:
        """`GCS_MAVLINK::accept_packet`: with MAV_OPTIONS bit 0 (4.5: SYSID_ENFORCE), only from a GCS sysid, the
        vehicle's own sysid (its components), or RADIO / RADIO_STATUS."""
        sysid = msg.get_srcSystem()
        return not self.params.gcs_only or self.params.is_gcs(sysid) or sysid == self.sub.sysid or \
            msg.get_type() in ("RADIO", "RADIO_STATUS")

    def _broadcast(self, msg) -> None:
        for link in self.links:
            link.send(msg)
