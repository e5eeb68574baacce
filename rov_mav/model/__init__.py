"""The vehicle model: parameters, the compiled 6-DOF dynamics and its matrix form, thrusters, environment, plant."""
