"""Control: the backstepping law and its disturbance adaptation (compiled and matrix forms), fuzzy rate schedules.

- backstepping: the report's law with its disturbance estimate, compiled
- controller: controller settings and the stateful controller stepped once per tick
- fuzzy: fuzzy adaptation rates (Mamdani inference, tabulated)
- ismc: integral sliding mode control, compiled
- law: the control and adaptation laws in matrix form: the statement the kernel is held to
- law_kernel: the controllers' one compiled interface
- pid: ArduSub-style cascade PID, compiled
- smc: sliding mode control per DOF, compiled
"""
