"""Subcommands of the rov-mav CLI, one module each, and what they share.

- analyze: review a dive afterwards
- autotune: excite, identify, tune and check the law on the vehicle, in one command
- arguments: command-line values checked where they enter
- bench: which controller tracks best, where, and how sure we are
- common: options shared by the commands that fly a mission
- identify: fit the vehicle model to logs and write a vehicle file
- missions: list the shipped missions and scenario sets
- run: fly a mission on a vehicle over MAVLink
- sim_bridge: run the built-in vehicle
- simulate: the closed loop offline
- tune: PSO tuning of a controller's gains
- vehicles: list the shipped vehicle files
"""
