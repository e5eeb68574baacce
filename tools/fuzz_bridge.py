"""The long fuzz run of the built-in vehicle: `rov-mav sim-bridge` with four fuzzed links (two UDP, two TCP) and a
checker's link, seeded traffic from `sim_bridge.transport.fuzz` (well-formed messages of every ardupilotmega type with
extreme
field values from random systems, and broken or random bytes), then the checks of tests/fuzz_helpers.py: the
vehicle still answers, its state and parameters are sane, its message intervals are within ArduPilot's limits, and
it handled every message without an exception.

Run:
    .venv/bin/python tools/fuzz_bridge.py [--chunks 150000] [--seed 1] [--speedup 10]
Prints progress, then the figures: chunks and well-formed messages sent, types covered, messages per second,
messages the bridge received, handler errors and problems found. Exit status 1 if any were found.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from fuzz_helpers import bridge_counters, check_vehicle, fuzz, fuzzed_bridge  # noqa: E402
from pymavlink.dialects.v20 import ardupilotmega as mavlink  # noqa: E402
from run_helpers import checker  # noqa: E402

PROGRESS_EVERY = 10_000


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--chunks", type=int, default=150_000, help="writes to send (default %(default)s)")
    parser.add_argument("--seed", type=int, default=1, help="seed of the traffic (default %(default)s)")
    parser.add_argument("--speedup", type=float, default=10.0, help="the bridge's --speedup (default %(default)s)")
    args = parser.parse_args()

    def progress(report):
        if report.chunks % PROGRESS_EVERY == 0:
            print(f"  {report.chunks} chunks, {report.messages} well-formed messages, {report.seconds:.0f} s",
                  flush=True)

    with tempfile.TemporaryDirectory() as tmp:
        bridge, links = fuzzed_bridge(Path(tmp), args.speedup)
        bridge.start()
        try:
            station = checker(bridge.port)
            try:
                report = fuzz(links, station, args.chunks, args.seed, progress)
                problems = check_vehicle(bridge, station, links)
            finally:
                station.close()
        finally:
            code = bridge.stop()
        output = bridge.output
    received, types, errors = bridge_counters(output)
    if code != 0:
        problems.append(f"the bridge exited with status {code}")
    broken = report.chunks - report.kinds["message"] - report.kinds["burst"] - report.kinds["signed"]
    print(f"seed {args.seed}: {report.chunks} chunks in {report.seconds:.1f} s on {len(links)} links "
          f"({report.chunks / report.seconds:.0f} chunks/s): {report.messages} well-formed messages "
          f"({report.messages / report.seconds:.0f}/s), {broken} broken or random writes "
          f"({', '.join(f'{k} {v}' for k, v in sorted(report.kinds.items()))})")
    print(f"types sent well-formed: {len(report.types)} of {len(mavlink.mavlink_map)} in the ardupilotmega dialect; "
          f"TCP reconnections: {report.reconnects}")
    lines = output.splitlines()
    print(next((line for line in lines if "stopped at" in line), "bridge: no summary line"))
    keys = sum("signing key set by SETUP_SIGNING" in line for line in lines)
    dropped = next((line.split(": ", 2)[2] for line in lines if "dropped for their signature" in line), "none")
    print(f"bridge: {received} messages received ({types} types), {errors} handler errors; the traffic's SETUP_SIGNING "
          f"gave it a key {keys} times (the checker turned signing off each time), frames dropped for their signature "
          f"meanwhile: {dropped}; the rest of the messages sent were lost behind broken frames, as a MAVLink "
          f"byte-stream parser loses them")
    print(f"problems found: {len(problems)}")
    for problem in problems:
        print(f"  {problem}")
    return 1 if problems or errors else 0


if __name__ == "__main__":
    sys.exit(main())
