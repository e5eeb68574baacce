"""The vehicle model: parameters, the compiled 6-DOF dynamics and its matrix form, thrusters, environment, plant.

- dynamics: the 6-DOF model in matrix form (the test oracle)
- environment: disturbance, current, sensor noise, the bottom and the ice (simulation only)
- frames: ArduSub's frames (FRAME_CONFIG) and their mixer tables
- kernel: the compiled 6-DOF model and RK4
- kernel_cache: when a cached compiled kernel is fresh
- navigation: the navigation presets and their sensors' figures
- seafloor: the bottom and the ice ceiling, a depth at every point
- plant: the true simulated vehicle, stepped by the bridge
- pretension: thrust along the allocation's null space, out of the dead band
- thrusters: allocation, the PWM <-> thrust map, wrench <-> thrust
- vehicle: the vehicle file, its validation, mass and restoring quantities
- vehicle_faults: the vehicle's faults on purpose, and their grammar
"""
