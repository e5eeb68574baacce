"""The bridge: the emulated ArduSub, its physics and its MAVLink links in one paced loop.

Each step of h simulated seconds: ArduSub's main loop (RC input, failsafes) -> servo outputs -> physics -> the
telemetry due on each link. Between steps the loop reads the links and sleeps until the next step is due on the
wall clock (`Pacer`). Run it blocking (`run()`, the CLI) or in a background thread (`start()` / `stop()`).
An exception while handling one received message is contained: counted in `handler_errors`, reported in one stderr
line, and the loop goes on (the fuzz test requires the count to stay 0: this is the last net, not the fix).
"""

from __future__ import annotations

import select
import sys
import threading
import time

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from rov_mav.model.plant import Plant
from rov_mav.model.thrusters import thruster_curve
from rov_mav.model.vehicle import load_vehicle
from sim_bridge import telemetry
from sim_bridge.ardusub import ArduSub
from sim_bridge.battery import Battery
from sim_bridge.config import BridgeConfig
from sim_bridge.faults import LinkFaults
from sim_bridge.link import Link, open_links
from sim_bridge.missions import MissionProtocol
from sim_bridge.pacing import Pacer
from sim_bridge.params import Params
from sim_bridge.physics import Physics
from sim_bridge.protocol import Protocol
from sim_bridge.schedule import Scheduler
from sim_bridge.signing import VehicleSigning

MAX_IDLE = 0.05                                   # s: longest sleep between checks for a stop request


class Bridge:
    """A simulated BlueROV2 Heavy running ArduSub, reachable over MAVLink."""

    def __init__(self, config: BridgeConfig = BridgeConfig()):
        if config.speedup <= 0:
            raise ValueError("speedup must be positive")
        self.config = config
        self.params = Params(config.firmware)
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
        self.vehicle = load_vehicle(config.vehicle_path)
        self.sub = ArduSub(self.params)
        plant = Plant(self.vehicle, config.environment, eta0=np.array([0, 0, config.start_depth, 0, 0, 0.0]),
                      seed=config.seed)
        Plant(self.vehicle).step(np.zeros(6), config.step)   # load the compiled model now, not in a paced step
        battery = Battery(self.params["SIM_BATT_VOLTAGE"], self.params["SIM_BATT_CAP_AH"])
        self.physics = Physics(self.vehicle, plant, battery, thruster_curve(self.vehicle), config.step)
        self.signing = VehicleSigning(config.signing_key, time.time())
        self.missions = MissionProtocol(lambda: config.origin)
        self.protocol = Protocol(self.sub, self.params, self.snapshot, self._params_changed, self.missions,
                                 self.signing)
        self.links: list[Link] = []
        self.schedulers: list[Scheduler] = []
        self.steps = 0
        self.messages_received = 0
        self.message_types: set[str] = set()      # of the dialect's types received (unknown ids not counted)
        self.handler_errors = 0
        self._step_us = round(config.step * 1e6)
        self.servo = self.sub.servo_outputs()
        self.estimate = plant.measured()          # (eta, nu) as the sensors give them now: the autopilot's view
        self.unix_start = time.time()
        self.pacer: Pacer | None = None
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None
        self.error: BaseException | None = None

    # -- lifecycle -------------------------------------------------------------------------------------------

    def open(self) -> None:
        """Open every link (LinkError, one line, if one cannot be opened)."""
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
        names = tuple(telemetry.BUILDERS)
        self.schedulers = [Scheduler(names, lambda g, ch=link.channel: self.params.stream_rate(ch, g))
                           for link in self.links]

    def close(self) -> None:
        for link in self.links:
            link.close()

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
        """Simulated time since boot, s."""
        return self.steps * self.physics.h

    def truth(self) -> tuple[float, np.ndarray, np.ndarray]:
        """(t, eta, nu) of the simulated vehicle, without sensor noise (copies; safe from any thread)."""
        with self._lock:
            plant = self.physics.plant
            return self.t, np.array(plant.eta, dtype=float), np.array(plant.nu, dtype=float)

    def snapshot(self) -> telemetry.Snapshot:
        """What the telemetry reports now (measured state, with the environment's sensor noise)."""
        eta, nu = self.estimate
        battery = self.physics.battery
        return telemetry.Snapshot(
            t_us=self.steps * self._step_us, eta=np.asarray(eta), nu=np.asarray(nu), servo=self.servo,
            rc_in=self.sub.rc.radio_in.copy(),
            base_mode=self.sub.base_mode(), custom_mode=self.sub.mode, system_status=self.sub.system_status(),
            throttle=float(self.sub.pilot_axes()[3]) if self.sub.armed else 0.0,
            voltage=battery.voltage, current=battery.current, consumed_ah=battery.consumed_ah,
            remaining=battery.remaining, origin=self.config.origin, water_density=self.vehicle.water_density,
            gravity=self.vehicle.gravity, unix_start=self.unix_start, firmware=self.params.firmware,
            mission_count=len(self.missions.items), safety_on=self.sub.safety_on)

    def _params_changed(self, t: float) -> None:
        for scheduler in self.schedulers:
            scheduler.refresh(t)

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
        self.sub.update(self.t, self.estimate)
        self.servo = self.sub.servo_outputs()
        with self._lock:
            self.physics.step(self.servo[:8])
            self.steps += 1
        self.estimate = self.physics.plant.measured()
        t = self.t
        while self.sub.texts:
            severity, text = self.sub.texts.pop(0)
            self._broadcast(telemetry.ENCODER.statustext_encode(severity, text.encode()[:50]))
        snap = None
        for link, scheduler in zip(self.links, self.schedulers):
            for name in scheduler.due(t):
                snap = snap or self.snapshot()
                link.send(telemetry.BUILDERS[name](snap))
            link.deliver()
        for channel, msg in self.missions.update(t):
            for link in self.links:
                if link.channel == channel:
                    link.send(msg)

    def _receive(self) -> None:
        t = self.t
        for link, scheduler in zip(self.links, self.schedulers):
            for msg in link.receive():
                self.messages_received += 1
                if msg.get_msgId() in mavlink.mavlink_map:
                    self.message_types.add(msg.get_type())
                try:
                    replies = self.protocol.handle(msg, link.channel, scheduler, t)
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

    def _broadcast(self, msg) -> None:
        for link in self.links:
            link.send(msg)
