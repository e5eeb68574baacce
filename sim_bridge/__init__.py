"""The built-in vehicle that speaks ArduSub MAVLink around the rov_mav 6-DOF model.

Run it with `rov-mav sim-bridge` (see its --help), or embed it:

    from sim_bridge.config import BridgeConfig
    from sim_bridge.server import Bridge

    bridge = Bridge(BridgeConfig(endpoints=("udpin:127.0.0.1:14551",), speedup=10))
    bridge.start()            # a background thread; connect to udpout:127.0.0.1:14551
    ...
    bridge.stop()

Modules, one concept each: params (ArduSub's parameter table), rc (RC input and overrides), mixer
(vectored_6dof), ardusub (arming, pilot and GCS failsafes, output routing), modes (mode numbers and the gates of a
mode change), stabilize (the assisted modes' holds), surface (SURFACE mode and the surface detector), failsafes
(leak, battery, EKF, depth sensor), battery, physics (PWM -> T200 -> lag -> wrench -> plant, thruster faults),
vehicle_faults (which fault is live), avionics (what the autopilot's sensors read), navigation (the EKF's estimate
and status), boot (power loss and boot), telemetry (message contents), schedule (message rates), protocol (answers
to GCS messages), link (UDP/TCP transports), pacing (simulated vs wall clock), server (the loop), config, cli.
"""
