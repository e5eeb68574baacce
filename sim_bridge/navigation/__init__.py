"""The vehicle's navigation: its sensors, the estimator, the EKF's aiding and status, the sources' own messages.

- attached: the sensors beyond the navigation suite, by their navigation: section
- aiding: the EKF's estimate and status under a lost position source (EKF_STATUS_REPORT, LOCAL_POSITION_NED)
- avionics: what the autopilot's sensors read during one boot, under the vehicle's faults
- estimate_errors: the navigation error along a path, for the offline loops
- echo_sounder: a Ping-like echo sounder: what its cone sees of the bottom or the ice, and its link message
- estimator: the Kalman filters standing in for EKF3
- sensors: the sensors, drawn from the plant's true state
- source_messages: what the navigation sources' BlueOS extensions put on the link
"""
