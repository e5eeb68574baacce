"""Missions: files -> smooth references, the lead-in to a mission's start, tracking metrics against a reference.

- approach: a lead-in from wherever the vehicle is to the mission's start pose
- autotune_plan: autotune's box: the excitation moved to the vehicle, the check square, their limits
- excitation: multisines and chirps for identification
- loader: any mission file into a Mission
- metrics: tracking metrics of a run, the same for simulate and run
- mission_items: MAVLink mission items read the way ArduSub reads them
- missions: a YAML path into a smooth reference
- qgc_plan: QGroundControl .plan files
- terrain: an altitude or standoff leg's depth made online: the surface's estimate and a flyable reference
"""
