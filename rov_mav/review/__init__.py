"""Reviewing a dive after the fact (`rov-mav analyze`): a run's log folder or any ArduSub telemetry log read back
(`tlog`, `runlog`), decoded as the runner decodes the live link (`dive`), set against a mission (`reference`),
measured (`analysis`) and shown as `simulate` shows a run (`outputs`)."""
