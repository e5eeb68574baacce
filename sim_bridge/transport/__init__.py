"""How the vehicle meets the world: MAVLink transports, faults on them, pacing against the wall clock, hostile traffic.

- faults: faults on the links, on purpose: loss, delay, jitter, duplication, reordering, a cut
- fuzz: hostile and broken MAVLink traffic, seeded
- link: the UDP and TCP transports
- pacing: a fixed-step simulation paced against the wall clock at a speedup
"""
