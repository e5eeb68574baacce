"""Reviewing a dive after the fact (`rov-mav analyze`).

- analysis: the figures that need no mission: loop, gaps, saturation, battery, modes, the vehicle's own sensors
- controller_tracking: ArduSub's and rov-mav's controllers against their own targets
- dataflash_log: a .BIN read as a dive
- dataflash_records: a .BIN's records as columns, by the file's own FMT labels
- dive: a telemetry log decoded as the runner decodes the live link
- dive_review: all of it, against a mission when there is one
- logdir: a run's --log folder read back
- onboard: a .BIN's EKF health and motor limits
- outputs: the figures and the Rerun recording
- reference: when a dive's mission started, and the vehicle's own mission path
- series: a logged series read at other times
- tlog: a .tlog read as far as it goes
"""
