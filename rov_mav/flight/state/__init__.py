"""Telemetry into the state the law flies on: decoded, shaped, carried to when the command acts; own navigation.

- estimate_blend: position and velocity blended from the vehicle's estimate (a complementary filter)
- estimate_jumps: a jump of the position estimate taken in at a pace the vehicle can fly
- estimate_shaping: the run's shaping of the estimate, one object for the run and the offline loops
- model_estimator: the run's own model-aided Kalman filter (run --estimator model)
- own_navigation: the navigation sources' messages turned into that filter's measurements, and its state
- prediction: the late state carried forward to the instant its command acts
- soundings: an echo sounder's DISTANCE_SENSOR readings, from its own service or the autopilot's copy
- vehicle_state: (t, eta, nu) decoded from ArduSub's ATTITUDE and LOCAL_POSITION_NED
"""
