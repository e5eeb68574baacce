"""Judging a telemetry stream before arming (rov_mav/flight/session/stream_rate.py): what the vehicle sends is read
through a
30 % loss, duplicates and reordering; a vehicle that sends too slowly, or a link that loses too much, is refused."""

from __future__ import annotations

import random

import numpy as np

from rov_mav.flight.session.stream_rate import measure, too_slow

ASKED = 50.0


def _received(send_hz: float, loss: float, seconds: float = 3.0, seed: int = 0) -> list[float]:
    """time_boot_ms stamps (s, whole ms as sent) of a stream at send_hz that survive a `loss`, shuffled a little."""
    rng = random.Random(seed)
    stamps = [round(k / send_hz, 3) for k in range(int(seconds * send_hz)) if rng.random() >= loss]
    for i in range(0, len(stamps) - 1, 17):                 # some neighbours swapped, some duplicated
        stamps[i], stamps[i + 1] = stamps[i + 1], stamps[i]
    return stamps + stamps[::23]


def test_a_30_percent_loss_reads_as_the_rate_sent_and_is_flown():
    rate = measure(_received(ASKED, 0.3))
    assert abs(rate.sent_hz - ASKED) < 0.5
    assert 0.6 * ASKED < rate.arriving_hz < 0.8 * ASKED
    assert abs(rate.lost - 0.3) < 0.1
    assert too_slow("ATTITUDE", rate, ASKED) is None


def test_a_vehicle_sending_too_slowly_is_refused_even_without_loss():
    why = too_slow("ATTITUDE", measure(_received(25.0, 0.0)), ASKED)
    assert why is not None and "the vehicle sends ATTITUDE at 25.0 Hz" in why and "lower --rate" in why


def test_a_link_losing_most_of_the_stream_is_refused():
    why = too_slow("LOCAL_POSITION_NED", measure(_received(ASKED, 0.6, seed=1)), ASKED)
    assert why is not None and "LOCAL_POSITION_NED arrives at" in why and "check the link" in why


def test_too_few_messages_measure_nothing():
    assert measure([]).sent_hz == 0.0 and measure([1.0, 1.0, 1.0]).arriving_hz == 0.0
    assert too_slow("ATTITUDE", measure(np.array([1.0, 1.02])), ASKED) is not None
