"""A run, phase by phase: what it is asked, claiming the vehicle, the outputs, the loop, the safe stop.

- assembly: a run built from what was asked, flown, closed on every path, and its metrics
- claim: identify the vehicle, hold its frame to the vehicle file, judge the link, take the GCS role
- control_loop: the ticks, the watchdog, the limits, stalls and the hand-over
- guided: --controller ardusub-guided: the reference streamed to ArduSub's GUIDED
- outputs: how the commands reach the thrusters, one strategy per path (passthrough, motor test, GUIDED)
- realtime: --realtime: ask the operating system to keep the loop running on a busy computer
- run_io: what every phase uses to reach the vehicle and the operator
- run_options: what a run is asked to do and how it ends
- runner: the phases composed
- safe_stop: on every exit path, undo what the run changed, step by step
- terrain_following: altitude and standoff legs: the sounder's readings into the depth the law flies
- thruster_watch: the answer to a thruster that does not do what it is told
"""
