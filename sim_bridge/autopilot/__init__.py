"""ArduSub's flight code on the built-in vehicle: parameters, pilot input, arming, modes, failsafes, the mixer.

- ardusub: the autopilot's loop: modes, arming, RC input, failsafes acted on, servo output routing
- arming: ArduSub's arming checks
- buttons: MANUAL_CONTROL's buttons as ArduSub acts on them
- failsafes: ArduSub's failsafes (failsafe.cpp): leak, battery, EKF, depth sensor, GCS and pilot input
- guided: GUIDED mode's position controller
- joystick: MANUAL_CONTROL into RC overrides, as ArduSub maps a pilot's joystick
- mixer: the 6-DOF motor mixer of the frame the vehicle booted with
- modes: the mode numbers and the gates a mode change passes
- params: ArduSub's parameters the vehicle uses, for 4.5 or 4.7
- rc: RC input fed only by GCS overrides
- stabilize: the assisted modes' attitude, depth and position holds
- surface: SURFACE mode and the surface detector
"""
