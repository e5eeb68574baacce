"""rov-mav: fuzzy-adaptive backstepping trajectory tracking for a BlueROV2 Heavy over MAVLink."""

__version__ = "0.1.0"
