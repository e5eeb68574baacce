"""Flying a vehicle over MAVLink, in rooms from the bottom up (each imports only the rooms listed before it):

- record/: what a run keeps and shows (ticks, the log folder, the status line)
- session/: the vehicle across the link (the session, other stations, its clock, events, frame, what a run changed)
- state/: telemetry into the state the law flies on (decoding, shaping, prediction, the run's own navigation)
- thrusters/: a wrench into PWMs, and whether each thruster obeys
- run/: a run, phase by phase (options, claim, outputs, the control loop, the safe stop)
"""
