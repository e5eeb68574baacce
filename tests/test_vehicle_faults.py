"""The vehicle-fault grammar (rov_mav.model.vehicle_faults): every item, what it means at a time, one-line errors,
the YAML forms, and the environment's `vehicle_faults`."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rov_mav.model.environment import load_environment
from rov_mav.model.vehicle_faults import (
    EXAMPLE,
    VehicleFaultError,
    VehicleFaults,
    load_vehicle_faults,
    parse_vehicle_faults,
)


def parse(text: str) -> VehicleFaults:
    return parse_vehicle_faults(text.split(","))


def test_the_example_parses_and_describes_itself_back():
    faults = parse(EXAMPLE)
    assert parse(faults.describe()) == faults
    assert faults.reboots == (90.0,) and faults.leak == 100.0 and faults.depth_sensor == 50.0
    assert faults.battery == (0.05, 0.0) and faults.navigation_lost == ((30.0, 10.0),)
    assert faults.autopilot_faults == ["reboot", "leak", "battery", "navigation-lost", "depth-sensor"]
    assert bool(faults) and not VehicleFaults() and VehicleFaults().describe() == "none"


def test_thruster_effects_over_time_a_later_fault_replaces_an_earlier_one():
    faults = parse("thruster=3:weak=0.4@10s,thruster=3:dead@20s,thruster=5:stuck=1700@5s,thruster=8:reversed@1s")
    gain, stuck = faults.thruster_effect(0.5)
    assert np.all(gain == 1) and np.all(np.isnan(stuck))
    gain, stuck = faults.thruster_effect(12.0)
    assert gain[2] == pytest.approx(0.4) and gain[7] == -1 and gain[4] == 1 and stuck[4] == 1700
    assert np.isnan(np.delete(stuck, 4)).all()
    gain, _ = faults.thruster_effect(20.0)
    assert gain[2] == 0
    assert faults.thruster_times() == (1.0, 5.0, 10.0, 20.0)


def test_events_in_time():
    faults = parse("reboot@90s,reboot@30s,leak@100s,battery=0.1V/s@10s,navigation-lost@30s+10s,"
                   "navigation-lost@60s,depth-sensor@500ms")
    assert faults.reboots == (30.0, 90.0)                           # sorted, repeatable
    assert not faults.leaking(99.9) and faults.leaking(100.0)
    assert faults.battery_sag(5.0) == 0 and faults.battery_sag(20.0) == pytest.approx(1.0)
    assert faults.navigation_ok(29.9) and not faults.navigation_ok(35.0) and faults.navigation_ok(40.0)
    assert not faults.navigation_ok(1e6)                            # without +D: for good
    assert faults.navigation_lost[1] == (60.0, math.inf)
    assert faults.depth_sensor_ok(0.4) and not faults.depth_sensor_ok(0.5)


@pytest.mark.parametrize("text, words", [
    ("thruster=9:dead@3s", "N from 1 to 8"),
    ("thruster=3:broken@3s", "unknown thruster fault 'broken'"),
    ("thruster=3:stuck=2500@3s", "PWM from 1100 to 1900"),
    ("thruster=3:weak=1.5@3s", "0 < K < 1"),
    ("thruster=3:dead=2@3s", "'dead' takes no value"),
    ("thruster=3:dead", "thruster=N:KIND@TIME"),
    ("reboot@soon", "a time of 0 or more with its unit"),
    ("reboot", "reboot@TIME"),
    ("leak@3s,leak@4s", "leak is given twice"),
    ("battery=fast", "RATE in volts per second"),
    ("battery=20V/s", "at most 10"),
    ("navigation-lost@3s+0s", "more than 0 s"),
    ("explode@3s", "unknown vehicle fault 'explode@3s'"),
])
def test_malformed_items_are_one_line_errors_naming_the_item(text, words):
    with pytest.raises(VehicleFaultError) as info:
        parse(text)
    message = str(info.value)
    assert words in message and "\n" not in message


def test_files_hold_vehicle_faults_as_text_or_a_list(tmp_path):
    as_text = tmp_path / "text.yaml"
    as_text.write_text('vehicle_faults: "thruster=2:dead@1s,reboot@5s"\n')
    as_list = tmp_path / "list.yaml"
    as_list.write_text("vehicle_faults:\n  - thruster=2:dead@1s\n  - reboot@5s\n")
    assert load_vehicle_faults(str(as_text)) == load_vehicle_faults(str(as_list)) == parse("thruster=2:dead@1s,reboot@5s")
    assert load_vehicle_faults("leak@3s") == parse("leak@3s")
    missing = tmp_path / "none.yaml"
    missing.write_text("other: 1\n")
    with pytest.raises(VehicleFaultError, match="vehicle_faults: missing"):
        load_vehicle_faults(str(missing))
    bad = tmp_path / "bad.yaml"
    bad.write_text('vehicle_faults: "leak@never"\n')
    with pytest.raises(VehicleFaultError, match=f"^{bad}: leak@never"):
        load_vehicle_faults(str(bad))
    with pytest.raises(VehicleFaultError, match="no such file"):
        load_vehicle_faults(str(tmp_path / "absent.yaml"))


def test_an_environment_carries_its_vehicle_faults(tmp_path):
    path = tmp_path / "env.yaml"
    path.write_text("environment:\n  vehicle_faults: [thruster=1:reversed@2s, leak@9s]\n")
    assert load_environment(path).vehicle_faults == parse("thruster=1:reversed@2s,leak@9s")
    path.write_text("environment:\n  vehicle_faults: thruster=0:dead@2s\n")
    with pytest.raises(Exception, match="N from 1 to 8"):
        load_environment(path)


def test_offline_thruster_faults_map_the_wrench_through_what_the_thrusters_still_give():
    from rov_mav.model.thrusters import allocation_matrix
    from rov_mav.model.vehicle import load_vehicle
    from rov_mav.model.vehicle_faults import wrench_map

    vehicle = load_vehicle(None)
    B = allocation_matrix(vehicle.thruster_positions, vehicle.thruster_directions)
    at, F, push = wrench_map(parse_vehicle_faults([]), B, lambda pwm: pwm)
    assert at == float("inf") and np.allclose(F, np.eye(6)) and not push.any()
    tau = np.array([10.0, -4.0, 6.0, 0.3, -0.2, 1.5])
    at, F, push = wrench_map(parse_vehicle_faults(["thruster=3:dead@5s", "thruster=6:stuck=1700@5s"]), B,
                             lambda pwm: np.full(len(pwm), 25.0))
    thrusts = np.linalg.pinv(B) @ tau                       # what the offline loop's allocation asks of each
    given = thrusts.copy()
    given[2], given[5] = 0.0, 25.0
    assert at == 5.0 and np.allclose(F @ tau + push, B @ given)
    with pytest.raises(VehicleFaultError, match="strike together"):
        wrench_map(parse_vehicle_faults(["thruster=3:dead@5s", "thruster=4:dead@6s"]), B, lambda pwm: pwm)


def test_an_offline_run_meets_its_thruster_fault_and_refuses_the_autopilots_faults(tmp_path):
    from rov_mav.config import ConfigError
    from rov_mav.control.controller import load_settings
    from rov_mav.mission.loader import load
    from rov_mav.model.vehicle import load_vehicle
    from rov_mav.offline.simulation import simulate

    settings, vehicle = load_settings("fuzzy"), load_vehicle(None)

    def mission(faults: str):
        path = tmp_path / "m.yaml"
        path.write_text("name: m\nstart: {position: [0.0, 0.0, 1.0], heading: 0.0}\n"
                        "path:\n  - {goto: [4.0, 0.0, 1.0], speed: 0.2}\n"
                        f"environment:\n  vehicle_faults: \"{faults}\"\n")
        return load(path)

    healthy = simulate(mission("thruster=3:dead@1000s"), settings, vehicle)
    dead = simulate(mission("thruster=3:dead@5s"), settings, vehicle)
    assert healthy.completed and dead.completed
    assert np.abs(dead.tau_hat[-1] - healthy.tau_hat[-1]).max() > 0.5   # the law holds against the missing thrust
    with pytest.raises(ConfigError, match="leak: only the built-in vehicle"):
        simulate(mission("leak@5s"), settings, vehicle)


def test_a_navigation_reset_moves_the_estimate_from_its_instant_and_resets_add_up():
    faults = parse_vehicle_faults(["navigation-reset=0.8/0.6@60s", "navigation-reset=-1/0@70s"])
    assert np.allclose(faults.navigation_offset(59.9), 0.0)
    assert np.allclose(faults.navigation_offset(60.0), [0.8, 0.6, 0.0])
    assert np.allclose(faults.navigation_offset(75.0), [-0.2, 0.6, 0.0])
    assert faults.autopilot_faults == ["navigation-reset"]
    assert parse_vehicle_faults(faults.describe().split(",")) == faults
    with pytest.raises(VehicleFaultError, match="NORTH/EAST@TIME"):
        parse_vehicle_faults(["navigation-reset=1@5s"])


@pytest.mark.parametrize("when,seconds", [("500ms", 0.5), ("90s", 90.0), ("1.5s", 1.5)])
def test_a_time_reads_alike_in_the_link_and_the_vehicle_fault_options(when, seconds):
    """Both grammars read their items through one parser (rov_mav.fault_items): the same '@TIME' is the same time."""
    from sim_bridge.transport.faults import parse_faults

    assert parse("reboot@" + when).reboots == (seconds,)
    assert parse_faults(f"cut=1s@{when}").cut == (seconds, 1.0)
    assert parse_faults(f"drop=PARAM_VALUE@{when}").drop == (("PARAM_VALUE", seconds),)
