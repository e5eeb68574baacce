"""Missions: files -> smooth references, the lead-in to a mission's start, tracking metrics against a reference."""
