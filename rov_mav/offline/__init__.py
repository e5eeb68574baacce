"""Offline work with no I/O to a vehicle: closed-loop simulation, PSO tuning, scenarios, figures."""
