"""The vehicle across the link: the session, who else is on it, its clock, what it says and is, what a run changed.

- link: the MAVLink session with ArduSub: connect, parameters, mode, arming, streams, overrides, motor tests
- stations: who else is on the link, and whose vehicle it is
- stream_rate: how fast a telemetry stream is sent and how much of it arrives, on the vehicle's own timestamps
- truth: the true position a simulator puts on the link (SIM_STATE)
- vehicle_changes: what a run changed on the vehicle, for the safe stop to undo
- vehicle_clock: the vehicle's clock mapped onto the wall clock; a reboot; a command's round trip
- vehicle_events: the vehicle's own failsafes and a reboot, which end a run
- vehicle_frame: the vehicle's frame and where its motors are, held to the vehicle file
- vehicle_mission: the mission stored on the vehicle, downloaded and read as a plan's items
- vehicle_position: where the vehicle is now, asked once without flying it
"""
