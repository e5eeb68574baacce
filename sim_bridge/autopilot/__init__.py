"""ArduSub's flight code on the built-in vehicle: parameters, pilot input, arming, failsafes, the loop, the mixer
(the modes' own controllers: `sim_bridge.modes`).

- ardusub: the autopilot's loop: modes, arming, RC input, failsafes acted on, servo output routing
- arming: ArduSub's arming checks
- buttons: MANUAL_CONTROL's buttons as ArduSub acts on them
- failsafes: ArduSub's failsafes (failsafe.cpp): leak, battery, EKF, depth sensor, GCS and pilot input
- joystick: MANUAL_CONTROL into RC overrides, as ArduSub maps a pilot's joystick
- mixer: the 6-DOF motor mixer of the frame the vehicle booted with
- params: ArduSub's parameters the vehicle uses, for 4.5 or 4.7
- rc: RC input fed only by GCS overrides
"""
