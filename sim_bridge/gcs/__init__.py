"""What ArduSub says and answers on its links.

- missions: the stored mission and the MAVLink mission protocol
- protocol: the answer to each message a ground station sends (GCS_MAVLINK)
- routing: MAVLink routing between the vehicle's links (MAVLink_routing.cpp)
- schedule: per-link message rates on the simulated clock
- signing: MAVLink 2 signing on every link (GCS_Signing.cpp)
- telemetry: the telemetry messages as ArduSub fills them
"""
