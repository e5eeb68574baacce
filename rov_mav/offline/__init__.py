"""Offline work with no I/O to a vehicle: closed-loop simulation, PSO tuning, scenarios, the bench, figures.

- autotune_report: autotune's one-page report and its figures
- bench: controllers tuned alike, judged on held-out scenarios over seeds
- bench_report: the bench's Markdown
- cluster: the tuner's Dask backend
- loop_kernel: the compiled batched closed loop and its costs
- noise: the compiled sensor-noise generator
- plots: figures of a run (PNG)
- pso: particle swarm optimization
- scenarios: the conditions a gain set is scored under
- simulation: one closed-loop simulation, no I/O
- tuning: what the tuner minimises
- identify/: the vehicle model fitted to logs (rov-mav identify)
"""
