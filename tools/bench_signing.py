"""Benchmark: what MAVLink 2 signing costs per message with pymavlink, on the messages a run exchanges.

For ATTITUDE (what the vehicle streams at the control rate) and RC_CHANNELS_OVERRIDE (what the runner sends at it):
the time to encode a message and to parse one, unsigned and signed (the parser checking with
`rov_mav.signing.check_signature_first` in place, as the runner and the bridge do), the best of REPEATS rounds (a
loaded machine only adds time), and what that comes to at the 500 messages per wall second of a 50 Hz run at
`--speedup 10`.
Run:
    .venv/bin/python tools/bench_signing.py [--messages 20000]
"""

from __future__ import annotations

import argparse
import time

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from rov_mav.signing import check_signature_first, key_from_passphrase, timestamp

RATE = 500                      # messages per wall second: 50 Hz at --speedup 10
REPEATS = 5


def _encoder(key: bytes | None) -> mavlink.MAVLink:
    mav = mavlink.MAVLink(None, 1, 1)
    if key is not None:
        mav.signing.secret_key, mav.signing.sign_outgoing = key, True
        mav.signing.timestamp = timestamp(time.time())
    return mav


def _parser(key: bytes | None) -> mavlink.MAVLink:
    mav = mavlink.MAVLink(None)
    mav.robust_parsing = True
    if key is not None:
        mav.signing.secret_key = key
        check_signature_first(mav)
    return mav


def _message(kind: str, mav: mavlink.MAVLink):
    if kind == "ATTITUDE":
        return mav.attitude_encode(123456, 0.01, -0.02, 1.5, 0.001, 0.002, 0.003)
    return mav.rc_channels_override_encode(1, 1, *([1550] * 8), *([0] * 10))


def measure(kind: str, key: bytes | None, n: int) -> tuple[float, float]:
    """(encode, parse) us per message, the best of REPEATS rounds of n."""
    rounds = [_round(kind, key, n) for _ in range(REPEATS)]
    return min(r[0] for r in rounds), min(r[1] for r in rounds)


def _round(kind: str, key: bytes | None, n: int) -> tuple[float, float]:
    encoder = _encoder(key)
    start = time.perf_counter()
    frames = [_message(kind, encoder).pack(encoder) for _ in range(n)]
    encode = (time.perf_counter() - start) / n * 1e6
    parser = _parser(key)
    start = time.perf_counter()
    parsed = [m for f in frames for m in parser.parse_buffer(f)]
    parse = (time.perf_counter() - start) / n * 1e6
    assert len(parsed) == n and all(m.get_type() == kind for m in parsed), "a frame failed to parse"
    return encode, parse


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--messages", type=int, default=10000, help="per round")
    args = ap.parse_args()
    key = key_from_passphrase("benchmark")
    print(f"{'message':<22}{'':>9}{'encode us':>11}{'parse us':>10}")
    for kind in ("ATTITUDE", "RC_CHANNELS_OVERRIDE"):
        plain = measure(kind, None, args.messages)
        signed = measure(kind, key, args.messages)
        for label, (enc, par) in (("unsigned", plain), ("signed", signed)):
            print(f"{kind:<22}{label:>9}{enc:11.2f}{par:10.2f}")
        extra = (signed[0] - plain[0]) + (signed[1] - plain[1])
        print(f"{'':<22}{'signing':>9} adds {extra:.2f} us per message (encode + parse): "
              f"{extra * RATE / 1e4:.2f} % of one core at {RATE} messages/s")


if __name__ == "__main__":
    main()
