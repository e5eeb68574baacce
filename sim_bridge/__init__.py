"""The built-in vehicle that speaks ArduSub MAVLink around the rov_mav 6-DOF model."""
