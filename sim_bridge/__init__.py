"""The built-in vehicle that speaks ArduSub MAVLink around the rov_mav 6-DOF model.

Run it with `rov-mav sim-bridge` (see its --help), or embed it:

    from sim_bridge.config import BridgeConfig
    from sim_bridge.server import Bridge

    bridge = Bridge(BridgeConfig(endpoints=("udpin:127.0.0.1:14551",), speedup=10))
    bridge.start()            # a background thread; connect to udpout:127.0.0.1:14551
    ...
    bridge.stop()

Rooms from the bottom up (each imports only the rooms listed before it), then the assembly:

- hardware/: physics, battery, power and boot, faults, the flight controller's arithmetic
- modes/: the flight modes' controllers, one file each as ArduSub's mode_*.cpp: holds, GUIDED, SURFACE, SURFTRAK,
  AUTO
- autopilot/: ArduSub's flight code: parameters, pilot input, arming, failsafes, the loop, the mixer
- gcs/: what ArduSub says and answers on its links: telemetry, schedule, protocol, missions, signing, routing
- navigation/: sensors, the estimator, the EKF's aiding and status, the navigation sources' messages, the sensors
  beyond them (an echo sounder)
- onboard_log/: the vehicle's own DataFlash log
- transport/: the MAVLink transports, faults on them, pacing, hostile traffic
- config: what a bridge is started with
- server: the bridge: one loop stepping every room
- process: the built-in vehicle in a process of its own, for `rov-mav run` without --target
"""
