"""Flying a vehicle over MAVLink: the session, telemetry -> state, actuation, the runner, its log and status line."""
