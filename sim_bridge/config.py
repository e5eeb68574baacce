"""What a bridge is started with: endpoints, speedup, firmware naming, environment, start state, link and vehicle
faults."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rov_mav.model.environment import Environment
    from rov_mav.model.navigation import Navigation
    from rov_mav.model.vehicle_faults import VehicleFaults
    from sim_bridge.transport.faults import FaultSpec

DEFAULT_OUT = "udpout:127.0.0.1:14550"
DEFAULT_ORIGIN = (-35.363261, 149.165230, 0.0)   # lat deg, lon deg, surface altitude m (ArduPilot SITL's home)
DEFAULT_STEP = 0.0025                             # s: ArduSub's 400 Hz main loop


@dataclass(frozen=True)
class BridgeConfig:
    """Endpoints are 'udpout:H:P', 'udpin:H:P' or 'tcpin:H:P'; params are initial parameter values by name."""

    endpoints: tuple[str, ...] = (DEFAULT_OUT,)
    speedup: float = 1.0
    firmware: str = "4.7"
    environment: Environment | None = None
    vehicle_path: str | None = None
    origin: tuple[float, float, float] = DEFAULT_ORIGIN
    start_depth: float = 0.0                          # m, at boot (level, heading north, at the origin)
    step: float = DEFAULT_STEP
    seed: int = 0                                     # of the sensor noise and the link faults
    faults: FaultSpec | None = None                   # degrade the links on purpose (sim_bridge/transport/faults.py)
    vehicle_faults: VehicleFaults | None = None       # None: the environment's (sim_bridge/hardware/vehicle_faults.py)
    params: dict[str, float] = field(default_factory=dict)
    signing_key: bytes | None = None                  # 32 bytes: MAVLink 2 signing on, as ArduSub with a stored key
    navigation: Navigation | None = None              # None: the environment's, else ideal (model/navigation.py)
    log_dir: str | None = None                        # the vehicle's own DataFlash logs (onboard_log/logger.py)
