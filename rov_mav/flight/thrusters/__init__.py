"""The thrusters: a wrench into PWMs within their limits, and whether each does what it is told.

- actuation: wrench -> thrusts -> PWMs at the battery voltage, within the thrust cap
- thruster_health: which thrusters do what they are told, from the vehicle's motion alone
"""
