"""rov-mav: fuzzy-adaptive backstepping trajectory tracking for a BlueROV2 Heavy over MAVLink.

Layers from the bottom up (tests/test_layers.py): the foundation, then model, control, mission, offline, flight,
telemetry, review; the command line on top.

- cli: the `rov-mav` command, one subcommand per module of commands/
- config: YAML files read with one-line, located errors
- fault_items: the grammar the link-fault and vehicle-fault options share (KEY=VALUE@TIME items, inline or a file)
- shipped: the missions, scenario sets and vehicles shipped in data/, found by name
- signing: MAVLink 2 signing shared by the runner and the built-in vehicle
- sitl: ArduPilot's ArduSub SITL as a child process, for tests and tools
- units: angles, durations and rates written with their units
- model/: the vehicle model: parameters, the compiled 6-DOF dynamics, thrusters, frames, faults
- control/: the controllers: the report's law, its adaptation, and the others on one compiled interface
- mission/: missions: files into smooth references, the lead-in, tracking metrics
- offline/: the closed loop without a vehicle: simulation, tuning, the bench, identification, figures
- flight/: flying a vehicle over MAVLink
- telemetry/: live and recorded telemetry in Rerun
- review/: a dive reviewed after the fact
- commands/: the subcommands
"""

__version__ = "0.1.0"
