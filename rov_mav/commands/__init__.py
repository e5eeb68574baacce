"""Subcommands of the rov-mav CLI, one module each."""
