"""The bridge's link faults (sim_bridge/transport/faults.py) as statistics over many messages with a seeded generator:
the loss
and duplication ratios, delays and their order, reordering, a cut, dropped types; and the option's validation."""

from __future__ import annotations

import math
import random

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sim_bridge.transport.faults import (REORDER_HOLD, Direction, FaultError, FaultSpec, load_faults, message_id,
                                         parse_faults)

N = 20000
PERIOD = 0.02            # vehicle s between messages: a 50 Hz stream
ATTITUDE = mavlink.MAVLINK_MSG_ID_ATTITUDE
PARAM_VALUE = mavlink.MAVLINK_MSG_ID_PARAM_VALUE


def _stream(spec: FaultSpec, n: int = N, seed: int = 1, msg_id: int = ATTITUDE) -> list[tuple[int, float]]:
    """Send messages 0..n-1 every PERIOD; returns (message number, arrival time) in arrival order, polled every
    2.5 ms as the bridge's loop does."""
    direction = Direction(spec, random.Random(seed))
    out = []
    t, k = 0.0, 0
    while k < n or t < n * PERIOD + 5.0:
        if k < n and k * PERIOD <= t:
            direction.send(k, msg_id, k * PERIOD)
            k += 1
        out += [(item, t) for item in direction.due(t)]
        t += 0.0025
    return out


def _within(observed: float, p: float, n: int = N) -> bool:
    """Within 5 standard deviations of a binomial proportion (fails by chance ~1 in 10^6)."""
    return abs(observed - p) <= 5 * math.sqrt(p * (1 - p) / n)


def test_loss_ratio_matches_the_probability():
    arrived = {k for k, _ in _stream(FaultSpec(loss=0.3))}
    assert _within(1 - len(arrived) / N, 0.3)


def test_duplication_ratio_matches_the_probability():
    got = [k for k, _ in _stream(FaultSpec(dup=0.05))]
    assert set(got) == set(range(N))
    assert _within((len(got) - N) / N, 0.05)


def test_delay_and_jitter_keep_the_order_and_bounds():
    delay, jitter = 0.05, 0.01
    got = _stream(FaultSpec(delay=delay, jitter=jitter))
    numbers = [k for k, _ in got]
    assert numbers == list(range(N))                       # jitter alone never reorders
    lateness = [t - k * PERIOD for k, t in got]
    assert min(lateness) >= delay - jitter - 1e-9
    assert max(lateness) <= delay + jitter + 0.0025 + 1e-9  # + one poll interval
    assert abs(sum(lateness) / N - (delay + 0.00125)) < 1e-3   # the mean delay (+ half a poll)


def test_reordering_swaps_neighbours_at_the_asked_rate():
    got = [k for k, _ in _stream(FaultSpec(reorder=0.1))]
    assert sorted(got) == list(range(N))                   # nothing lost or duplicated
    swaps = sum(1 for a, b in zip(got, got[1:]) if b < a)
    assert all(a - b == 1 for a, b in zip(got, got[1:]) if b < a)   # each overtaken by its successor only
    assert _within(swaps / N, 0.1 * 0.9, N)                # held (0.1), and the next one not held itself


def test_a_lone_held_message_still_arrives():
    direction = Direction(FaultSpec(reorder=1.0), random.Random(0))
    direction.send("only", ATTITUDE, 1.0)
    assert direction.due(1.0 + REORDER_HOLD / 2) == []
    assert direction.due(1.0 + REORDER_HOLD) == ["only"]


def test_a_cut_passes_nothing_sent_during_it():
    got = _stream(FaultSpec(cut=(10.0, 4.0)), n=1000)
    sent_at = [k * PERIOD for k, _ in got]
    assert not any(10.0 <= t < 14.0 for t in sent_at)
    assert len(got) == 1000 - 200


def test_a_dropped_type_never_arrives_from_its_start():
    spec = parse_faults("drop=PARAM_VALUE@5s")
    assert len(_stream(spec, n=1000, msg_id=ATTITUDE)) == 1000
    got = _stream(spec, n=1000, msg_id=PARAM_VALUE)
    assert [k for k, _ in got] == list(range(250))        # sent before 5 s only


def test_the_same_seed_gives_the_same_run_and_another_seed_another():
    spec = FaultSpec(loss=0.2, delay=0.05, jitter=0.01, dup=0.02, reorder=0.05)
    assert _stream(spec, n=2000, seed=7) == _stream(spec, n=2000, seed=7)
    assert _stream(spec, n=2000, seed=7) != _stream(spec, n=2000, seed=8)


def test_message_id_read_from_an_encoded_frame():
    enc = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    frame = enc.param_value_encode(b"SERVO1_FUNCTION", 33.0, 2, 100, 0).pack(enc)
    assert message_id(frame) == PARAM_VALUE
    assert message_id(b"\x00\x01") == -1


def test_the_option_parses_every_key():
    spec = parse_faults("loss=20%,delay=50ms,jitter=0.01s,dup=0.01,reorder=0.05,cut=30s@20s,drop=param_value@4s,"
                        "drop=COMMAND_ACK,link=1")
    assert spec == FaultSpec(loss=0.2, delay=0.05, jitter=0.01, dup=0.01, reorder=0.05, cut=(20.0, 30.0),
                             drop=(("PARAM_VALUE", 4.0), ("COMMAND_ACK", 0.0)), link=1)
    assert parse_faults(spec.describe()) == spec


def test_a_yaml_file_holds_the_same_keys(tmp_path):
    path = tmp_path / "faults.yaml"
    path.write_text("loss: 10%\ndelay: 100ms\ncut: 5s@30s\ndrop: [PARAM_VALUE@40s]\n")
    assert load_faults(str(path)) == FaultSpec(loss=0.1, delay=0.1, cut=(30.0, 5.0), drop=(("PARAM_VALUE", 40.0),))


@pytest.mark.parametrize("text,says", [
    ("loss=1.5", "loss=1.5: expected a probability"),
    ("loss=nan", "loss=nan: expected a probability"),
    ("delay=50", "delay=50: expected a time"),
    ("jitter=-5ms", "jitter=-5ms: expected a time"),
    ("delay=infs", "delay=infs: expected a time"),
    ("cut=30s", "cut=30s: expected LENGTH@START"),
    ("cut=0s@1s", "the cut must last more than 0 s"),
    ("cut=2s@-1s", "cut=2s@-1s: expected LENGTH@START, times of 0 or more"),
    ("drop=PARAM_VALUE@soon", "drop=PARAM_VALUE@soon: expected MESSAGE@START"),
    ("drop=NOPE@1s", "NOPE is not a MAVLink message"),
    ("link=-1", "link=-1: expected the position"),
    ("loss=0.1,loss=0.2", "loss is given twice"),
    ("speed=3", "unknown fault 'speed'"),
    ("loss=0.1,dup", "'dup': expected KEY=VALUE"),
    ("missing.yaml", "missing.yaml: no such file (nor KEY=VALUE"),
])
def test_bad_descriptions_are_one_line_errors(text, says):
    with pytest.raises(FaultError) as err:
        load_faults(text)
    assert says in str(err.value) and "\n" not in str(err.value)


def test_a_bad_file_names_itself(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text("loss: 3\n")
    with pytest.raises(FaultError, match=r"bad.yaml: loss=3: expected a probability"):
        load_faults(str(path))
    path.write_text("- loss\n")
    with pytest.raises(FaultError, match=r"bad.yaml: expected a mapping"):
        load_faults(str(path))
