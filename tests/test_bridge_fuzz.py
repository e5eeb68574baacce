"""The built-in vehicle survives any traffic: a `rov-mav sim-bridge` process with four fuzzed links (two UDP, two TCP)
takes seeded well-formed messages of every ardupilotmega type with extreme field values from random systems
(including the GCS's 255 and its own 1) and broken or random bytes, and afterwards still answers, has a consistent
state, sane parameters and message intervals, and raised no exception handling any of it.
(tools/fuzz_bridge.py is the long run of the same.)"""

from __future__ import annotations

import pytest
from fuzz_helpers import bridge_counters, check_vehicle, fuzz, fuzzed_bridge, read_all_params
from pymavlink.dialects.v20 import ardupilotmega as mavlink
from run_helpers import checker

from sim_bridge.autopilot.params import Params

pytestmark = pytest.mark.process      # starts a process or the bridge (tests/conftest.py)

CHUNKS = 4000
SEED = 9


def test_vehicle_survives_fuzzed_traffic_on_four_links(tmp_path):
    bridge, links = fuzzed_bridge(tmp_path)
    with bridge:
        station = checker(bridge.port)
        try:
            report = fuzz(links, station, CHUNKS, SEED)
            problems = check_vehicle(bridge, station, links)
            params = read_all_params(station)
        finally:
            station.close()
    assert not problems, "\n".join(problems)
    received, types, errors = bridge_counters(bridge.output)
    assert errors == 0 and "error handling" not in bridge.output, bridge.output
    assert len(report.types) == types == len(mavlink.mavlink_map)      # every type sent, and received whole
    assert received > report.messages / 3          # the rest lost behind broken frames or while a key was set
    defaults = {spec.name: spec.default for spec in Params().specs}
    changed = [name for name, m in params.items() if m.param_value != defaults[name]]
    assert len(changed) >= 5, changed                                  # the traffic reached the handlers
