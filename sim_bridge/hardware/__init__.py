"""The vehicle's hardware: its physics, battery, power and boot, faults, and the flight controller's arithmetic.

- battery: open-circuit voltage from the state of charge, less the internal resistance's drop
- boot: power loss and the boot after it, on the vehicle's clock
- numeric: C's numeric conversions and float comparisons as ArduSub performs them
- physics: PWM -> thrust -> lag -> body wrench -> the shared 6-DOF plant; the battery drained
- vehicle_faults: which of the vehicle's faults strike at a vehicle time
"""
