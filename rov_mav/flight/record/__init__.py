"""What a run keeps and shows.

- history: every tick's figures for the final metrics, in columns that grow without a Python object per value
- runlog: the run log folder (--log DIR): ticks.csv, events.csv, mavlink.tlog, run.json
- status: the terminal's live status line and the events
- tick: one control tick's record, for the run log and live telemetry
"""
