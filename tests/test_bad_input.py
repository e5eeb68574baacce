"""No traceback for any input: every command answers a bad file, number, connection string or output path with
one stderr line naming it, exit status 2, and nothing written.

Each case runs `rov-mav` in-process (`cli.main`) from an empty working folder, so that any default output (out/...)
would show up there; the checks that need a real process (an unreadable file, an unwritable folder, the exit of the
console script itself) run one as a subprocess.
"""

from __future__ import annotations

import ctypes
import os
import struct
import subprocess
import sys
import zlib
from pathlib import Path

import pytest
import yaml
from cli_helpers import assert_one_line, files_under, rov_mav
from conftest import MISSIONS

from rov_mav import cli
from rov_mav.config import MAX_FILE_BYTES

SQUARE = str(MISSIONS / "square.yaml")
ROBUST = str(MISSIONS / "scenarios" / "robust.yaml")


def png() -> bytes:
    """A valid 1 x 1 grey PNG."""
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
    header = struct.pack(">IIBBBBB", 1, 1, 8, 0, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(b"\0\0")) + chunk(b"IEND", b"")


def billion_laughs() -> str:
    """Nine levels of nine aliases each: 9^9 (387 million) strings once expanded, 0.3 kB on disk."""
    lines = ['a: &a ["x", "x", "x", "x", "x", "x", "x", "x", "x"]']
    for prev, name in zip("abcdefgh", "bcdefghi", strict=True):
        lines.append(f"{name}: &{name} [{', '.join(['*' + prev] * 9)}]")
    return "\n".join(lines) + "\npath: *i\n"


def make_bad_file(folder: Path, kind: str) -> Path:
    """A file (or not) of one bad kind, named after it."""
    path = folder / f"{kind}.yaml"
    if kind == "png":
        path = folder / "picture.png"
        path.write_bytes(png())
    elif kind == "empty":
        path.write_bytes(b"")
    elif kind == "comments":
        path.write_text("# nothing but a comment\n")
    elif kind == "directory":
        path.mkdir()
    elif kind == "huge":               # 200 MB, sparse: instant to make, and must not be read
        with open(path, "wb") as f:
            f.truncate(200 * 1024 * 1024)
    elif kind == "fifo":               # opening it for reading would wait forever for a writer
        os.mkfifo(path)
    elif kind == "missing":
        pass
    elif kind == "latin1":
        path.write_bytes(b"name: caf\xe9\n")
    elif kind == "bomb":
        path.write_text(billion_laughs())
    elif kind == "deep":               # deeper than ours, within libyaml's own limit (1,000 since PyYAML 6.0.4)
        path.write_text("path: " + "[" * 100 + "]" * 100 + "\n")
    elif kind == "very_deep":          # a C parser recursing this deep would overflow its stack
        path.write_text("path: " + "[" * 100_000 + "]" * 100_000 + "\n")
    elif kind == "self_alias":
        path.write_text("path: &p [1, *p]\n")
    elif kind == "list":
        path.write_text("- 1\n- 2\n")
    elif kind == "long_integer":
        path.write_text(f"k1: {'9' * 5000}\n")
    elif kind == "broken_yaml":
        path.write_text("path: [1, 2\n")
    else:
        raise ValueError(kind)
    return path


BAD_FILES = {   # kind -> what the one line must say
    "png": "not a text YAML file (binary)",
    "empty": "empty (no keys)",
    "comments": "empty (no keys)",
    "directory": "is a directory, expected a file",
    "huge": f"too large (209,715,200 bytes; at most {MAX_FILE_BYTES:,})",
    "fifo": "not a regular file",
    "missing": "no such file",
    "latin1": "not a text YAML file (byte 0xe9 at offset 9 is not UTF-8)",
    "bomb": "more than 100,000 values once aliases are expanded",
    "deep": "nested more than 50 levels deep",
    "very_deep": "nest",   # ours, or libyaml's "exceeded maximum nesting depth" (PyYAML >= 6.0.4) as it scans ahead
    "self_alias": "alias *p refers to the value that contains it",
    "list": "expected a mapping of keys at the top level",
    "long_integer": "Exceeds the limit (4300 digits) for integer string conversion",
    "broken_yaml": "(line 2): did not find expected ',' or ']'",
}

FILE_OPTIONS = {   # where a file enters: argv with {} for the file
    "run mission": ["run", "{}"],
    "simulate mission": ["simulate", "{}"],
    "tune mission": ["tune", "{}"],
    "run --gains": ["run", SQUARE, "--gains", "{}"],
    "simulate --vehicle": ["simulate", SQUARE, "--vehicle", "{}"],
    "simulate --plant-params": ["simulate", SQUARE, "--plant-params", "{}"],
    "tune --fuzzy-rules": ["tune", SQUARE, "--fuzzy-rules", "{}"],
    "tune --scenarios": ["tune", SQUARE, "--scenarios", "{}"],
    "tune --bounds-file": ["tune", SQUARE, "--bounds-file", "{}"],
    "bench --missions": ["bench", "--missions", SQUARE, "{}"],
    "bench --scenarios": ["bench", "--missions", SQUARE, "--training", ROBUST, "--scenarios", "{}"],
    "bench --training": ["bench", "--missions", SQUARE, "--scenarios", ROBUST, "--training", "{}"],
    "sim-bridge --environment": ["sim-bridge", "--environment", "{}"],
    "sim-bridge --vehicle": ["sim-bridge", "--vehicle", "{}"],
}


@pytest.fixture
def workdir(tmp_path, monkeypatch):
    """An empty working folder (default outputs would land in it) and a folder of inputs beside it."""
    work = tmp_path / "work"
    work.mkdir()
    (tmp_path / "inputs").mkdir()
    monkeypatch.chdir(work)
    return work


@pytest.mark.parametrize("kind", list(BAD_FILES))
@pytest.mark.parametrize("where", list(FILE_OPTIONS))
def test_bad_files(workdir, capsys, where, kind):
    bad = make_bad_file(workdir.parent / "inputs", kind)
    argv = [str(bad) if arg == "{}" else arg for arg in FILE_OPTIONS[where]]
    before = files_under(workdir.parent)
    status, err = rov_mav(argv, capsys)
    assert status == 2
    assert_one_line(err, f"rov-mav {argv[0]}: error: {bad}", BAD_FILES[kind])
    assert files_under(workdir.parent) == before


KEY_FILES = {   # a --signing-key file of a bad kind -> what the line must say
    "png": "a key file holds exactly 32 raw bytes, this one 67",
    "empty": "a key file holds exactly 32 raw bytes, this one 0",
    "directory": "is a directory, expected a file",
    "huge": "too large (209,715,200 bytes",
    "fifo": "not a regular file",
    "missing": "no such file",
}


@pytest.mark.parametrize("kind", list(KEY_FILES))
@pytest.mark.parametrize("command", [["run", SQUARE], ["sim-bridge"]], ids=["run", "sim-bridge"])
def test_bad_signing_key_files(workdir, capsys, command, kind):
    bad = make_bad_file(workdir.parent / "inputs", kind)
    status, err = rov_mav([*command, "--signing-key", str(bad)], capsys)
    assert status == 2
    assert_one_line(err, f"rov-mav {command[0]}: error: --signing-key {bad}", KEY_FILES[kind])
    assert files_under(workdir) == set()


def write_yaml(path: Path, data) -> Path:
    path.write_text(yaml.safe_dump(data))
    return path


def square_with(change) -> dict:
    data = yaml.safe_load(Path(SQUARE).read_text())
    change(data)
    return data


WRONG_VALUES = {   # a file's content -> the key and reason the line must give
    "speed NaN": (lambda d: d["path"][0].update(speed=float("nan")), "path[0].speed: Input should be a finite number"),
    "disturbance inf": (lambda d: d["environment"].update(disturbance=[float("inf")] * 6),
                        "environment.disturbance[0]: Input should be a finite number"),
    "heading 'inf deg'": (lambda d: d["path"][1].update(heading="inf deg"), "path[1].heading: Input should be a finite"),
    "speed a string": (lambda d: d["path"][0].update(speed="fast"), "path[0].speed: Input should be a valid number"),
    "speed negative": (lambda d: d["path"][0].update(speed=-0.2), "path[0].speed: Input should be greater than 0"),
    "speed out of range": (lambda d: d["path"][0].update(speed=1e300), "path[0].speed: Input should be less than or"),
    "waypoint out of range": (lambda d: d["path"][0].update(goto=[1e300, 0, 1]),
                              "path[0].goto[0]: Input should be less than or equal to 10000"),
    "hold of zero": (lambda d: d["path"][1].update(hold=0), "path[1].hold: Input should be greater than or equal"),
    "days long": (lambda d: d["path"][0].update(speed=1e-9), "path: lasts 1e+10 s, more than 86400 s (24 h)"),
    "too long to simulate": (lambda d: d["path"].append({"hold": 20_000}),
                             "20228 s in steps of 0.01 s is more than 1,440,000 steps (14400 s): too long"),
    "name a path": (lambda d: d.update(name="../../etc"), "name: must be usable as a folder name"),
    "path a mapping": (lambda d: d.update(path={"goto": 1}), "path: Input should be a valid list"),
    "limits a number": (lambda d: d.update(limits=3), "limits: Input should be a valid dictionary"),
    "max_tilt past 90 deg": (lambda d: d.update(limits={"max_tilt": "95 deg"}), "limits.max_tilt: Input should be "
                                                                               "less than 1.57"),
    "max_tilt without a unit": (lambda d: d.update(limits={"max_tilt": 15}), "limits.max_tilt: 15 is more than 2 pi "
                                                                           "radians: degrees need a unit"),
}


@pytest.mark.parametrize("case", list(WRONG_VALUES))
def test_wrong_values_in_a_mission(workdir, capsys, case):
    change, reason = WRONG_VALUES[case]
    mission = write_yaml(workdir.parent / "inputs" / "m.yaml", square_with(change))
    status, err = rov_mav(["simulate", str(mission)], capsys)
    assert status == 2
    assert_one_line(err, f"rov-mav simulate: error: {mission}: {reason}")
    assert files_under(workdir) == set()


@pytest.mark.parametrize("option, content, reason", [
    ("--vehicle", {"mass": float("inf")}, "mass: Input should be a finite number"),
    ("--vehicle", {"center_of_gravity": [1e300, 0, 0]}, "center_of_gravity[0]: Input should be less than or equal"),
    ("--gains", {"k1": [float("nan")] * 6}, "k1[0]: Input should be a finite number"),
    ("--gains", {"k1": "fast"}, "k1: Input should be a valid list"),
    ("--fuzzy-rules", {"output_points": 10**12}, "output_points: Input should be less than or equal to 100000"),
])
def test_wrong_values_in_other_files(workdir, capsys, option, content, reason):
    default = {"--vehicle": "bluerov2_heavy.yaml", "--gains": "controller.yaml", "--fuzzy-rules": "fuzzy_rules.yaml"}
    data = yaml.safe_load((Path(cli.__file__).parent / "data" / default[option]).read_text())
    data.update(content)
    bad = write_yaml(workdir.parent / "inputs" / "f.yaml", data)
    status, err = rov_mav(["simulate", SQUARE, option, str(bad)], capsys)
    assert status == 2
    assert_one_line(err, f"rov-mav simulate: error: {bad}: {reason}")
    assert files_under(workdir) == set()


@pytest.mark.parametrize("controller, content, reason", [
    ("pid", {"k1": [1.0] * 6}, "k1: unknown key"),           # another family's gains file
    ("fuzzy", {"kp_vel": [1.0] * 6}, "kp_vel: unknown key"),
    ("pid", {"kp_vel": [0.0] * 6}, "kp_vel[0]: Input should be greater than 0"),
    ("pid", {"ki_vel": [-1.0] * 6}, "ki_vel[0]: Input should be greater than or equal to 0"),
    ("smc", {"phi": [0.1] * 5}, "phi: List should have at least 6 items"),
    ("ismc", {"k": [float("inf")] * 6}, "k[0]: Input should be a finite number"),
])
def test_wrong_gains_for_the_chosen_controller(workdir, capsys, controller, content, reason):
    bad = write_yaml(workdir.parent / "inputs" / "g.yaml", content)
    status, err = rov_mav(["simulate", SQUARE, "--controller", controller, "--gains", str(bad)], capsys)
    assert status == 2
    assert_one_line(err, f"rov-mav simulate: error: {bad}: {reason}")
    assert files_under(workdir) == set()


def test_k1_with_a_controller_that_has_none(workdir, capsys):
    status, err = rov_mav(["simulate", SQUARE, "--controller", "smc", "--k1", "1,1,1,1,1,1"], capsys)
    assert status == 2
    assert_one_line(err, "rov-mav simulate: error: --k1: a gain of the backstepping law")
    assert files_under(workdir) == set()


BAD_NUMBERS = [   # argv -> the option the line must name
    (["run", SQUARE, "--sysid", "999"], "--sysid", "expected an integer from 1 to 255"),
    (["run", SQUARE, "--sysid", "0"], "--sysid", "expected an integer from 1 to 255"),
    (["run", SQUARE, "--sysid", "nan"], "--sysid", "not an integer"),
    (["run", SQUARE, "--rate", "nan"], "--rate", "expected a number from 1 to 400"),
    (["run", SQUARE, "--rate", "inf"], "--rate", "expected a number from 1 to 400"),
    (["run", SQUARE, "--rate", "0"], "--rate", "expected a number from 1 to 400"),
    (["run", SQUARE, "--rate", "-50"], "--rate", "expected a number from 1 to 400"),
    (["run", SQUARE, "--speedup", "inf"], "--speedup", "expected a number above 0 and at most 1000"),
    (["run", SQUARE, "--speedup", "0"], "--speedup", "expected a number above 0"),
    (["run", SQUARE, "--approach-speed", "-0.2"], "--approach-speed", "expected a number above 0 and at most 10"),
    (["run", SQUARE, "--approach-speed", "1e9"], "--approach-speed", "expected a number above 0 and at most 10"),
    (["run", SQUARE, "--link-timeout", "nan"], "--link-timeout", "expected a number above 0 and at most 60"),
    (["run", SQUARE, "--heartbeat-timeout", "1e300"], "--heartbeat-timeout", "at most 3600"),
    (["run", SQUARE, "--position-timeout", "0"], "--position-timeout", "expected a number above 0"),
    (["run", SQUARE, "--max-depth", "-1"], "--max-depth", "expected a number above 0"),
    (["run", SQUARE, "--max-thrust", "inf"], "--max-thrust", "expected a number above 0"),
    (["run", SQUARE, "--max-tracking-error", "nan"], "--max-tracking-error", "expected a number above 0"),
    (["run", SQUARE, "--max-tilt", "90"], "--max-tilt", "expected a number above 0 and at most 89"),
    (["run", SQUARE, "--baud", "0"], "--baud", "expected an integer from 1 to 10000000"),
    (["run", SQUARE, "--k1", "1,2,3,4,5,nan"], "--k1", "NaN or infinity"),
    (["run", SQUARE, "--k2", "1,2,3"], "--k2", "3 values, expected 6"),
    (["simulate", SQUARE, "--duration", "inf"], "--duration", "expected a number above 0 and at most 86400"),
    (["simulate", SQUARE, "--duration", "-3"], "--duration", "expected a number above 0"),
    (["simulate", SQUARE, "--seed", "-1"], "--seed", "expected an integer from 0 to 4294967295"),
    (["tune", SQUARE, "--particles", "0"], "--particles", "expected an integer from 1 to 10000"),
    (["tune", SQUARE, "--particles", "1e12"], "--particles", "not an integer"),
    (["tune", SQUARE, "--iterations", "-4"], "--iterations", "expected an integer from 1 to 100000"),
    (["tune", SQUARE, "--threads", "100000"], "--threads", "expected an integer from 1 to 256"),
    (["tune", SQUARE, "--w", "nan"], "--w", "expected a number from -10 to 10"),
    (["tune", SQUARE, "--c2", "1e999"], "--c2", "expected a number from -10 to 10"),
    (["tune", SQUARE, "--velocity-clamp", "0"], "--velocity-clamp", "expected a number above 0 and at most 1"),
    (["tune", SQUARE, "--bounds", "1,inf"], "--bounds", "need 0 < LO < HI, both finite"),
    (["tune", SQUARE, "--bounds", "nan,1"], "--bounds", "need 0 < LO < HI, both finite"),
    (["sim-bridge", "--speedup", "nan"], "--speedup", "expected a number above 0 and at most 1000"),
    (["sim-bridge", "--step", "0"], "--step", "expected a number from 0.0001 to 0.01"),
    (["sim-bridge", "--start-depth", "-1"], "--start-depth", "expected a number from 0 to 300"),
    (["sim-bridge", "--origin", "91,0"], "--origin", "need -90 <= LAT <= 90"),
    (["sim-bridge", "--origin", "nan,0,0"], "--origin", "need -90 <= LAT <= 90"),
    (["sim-bridge", "--seed", "-1"], "--seed", "expected an integer from 0 to 4294967295"),
    (["sim-bridge", "--param", "FS_PILOT_INPUT=1e39"], "--param", "must be a finite 32-bit float"),
    (["sim-bridge", "--param", "FS_PILOT_INPUT=nan"], "--param", "must be a finite 32-bit float"),
    (["sim-bridge", "--param", "=1"], "--param", "expected NAME=VALUE"),
    (["sim-bridge", "--link-faults", "loss=nan"], "--link-faults", "expected a probability from 0 to 1"),
    (["sim-bridge", "--link-faults", "delay=infms"], "--link-faults", "expected a time of 0 or more"),
    (["sim-bridge", "--link-faults", "cut=1e400s@1s"], "--link-faults", "times of 0 or more with their unit"),
]


@pytest.mark.parametrize("argv, option, reason", BAD_NUMBERS, ids=lambda v: " ".join(v[-2:]) if isinstance(v, list)
                         else None)
def test_bad_numbers(workdir, capsys, argv, option, reason):
    status, err = rov_mav(argv, capsys)
    assert status == 2
    assert_one_line(err, f"rov-mav {argv[0]}: error: argument {option}: {argv[-1]}", reason)
    assert files_under(workdir) == set()


BAD_CONNECTIONS = [
    (["run", SQUARE, "--target", "garbage:xyz"], "--target", "expected udp, udpin, udpout, udpbcast, tcp, tcpin:HOST"),
    (["run", SQUARE, "--target", "tcp:host:notaport"], "--target", "port must be a number from 1 to 65535"),
    (["run", SQUARE, "--target", "udp:[::1"], "--target", "expected udp/udpin/udpout/udpbcast/tcp/tcpin:HOST:PORT"),
    (["run", SQUARE, "--target", "udpin:0.0.0.0:99999"], "--target", "port must be a number from 1 to 65535"),
    (["run", SQUARE, "--target", "udpout:bad host:14550"], "--target", "'bad host' is not a host name or IPv4"),
    (["run", SQUARE, "--target", "/dev/ttyNO_SUCH_DEVICE"], "--target", "no such serial device"),
    (["run", SQUARE, "--target", SQUARE], "--target", "not a serial device"),
    (["run", SQUARE, "--target", ""], "--target", "empty connection string"),
    (["sim-bridge", "--out", "garbage:xyz"], "--out", "expected udpout:HOST:PORT"),
    (["sim-bridge", "--out", ""], "--out", "empty connection string"),
    (["sim-bridge", "--listen", "udpin:0.0.0.0:99999"], "--listen", "port must be a number from 1 to 65535"),
    (["sim-bridge", "--listen", "tcpin:[::1]:5760"], "--listen", "expected udpin:HOST:PORT or tcpin:HOST:PORT"),
    (["sim-bridge", "--listen", "tcpin:127.0.0.1:port"], "--listen", "port must be a number from 1 to 65535"),
    (["tune", SQUARE, "--cluster", "tcp://scheduler:99999"], "--cluster", "expected tcp://HOST:PORT"),
    (["tune", SQUARE, "--cluster", "local:0"], "--cluster", "number of workers N from 1 to 256"),
    (["run", SQUARE, "--rerun", "connect:rerun+http://viewer:99999/proxy"], "--rerun", "port must be a number"),
    (["run", SQUARE, "--rerun", "connect:garbage"], "--rerun", "expected a viewer URL"),
]


@pytest.mark.parametrize("argv, option, reason", BAD_CONNECTIONS, ids=lambda v: " ".join(v[-2:])
                         if isinstance(v, list) else None)
def test_bad_connection_strings(workdir, capsys, argv, option, reason):
    status, err = rov_mav(argv, capsys)
    assert status == 2
    assert_one_line(err, f"rov-mav {argv[0]}: error: argument {option}: ", reason)
    assert files_under(workdir) == set()


def test_a_device_that_is_no_serial_port_is_a_one_line_refusal(workdir, capsys):
    """/dev/null passes as a character device; opening it as a serial port fails at once, in one line (status 1:
    the link, not the arguments)."""
    status, err = rov_mav(["run", SQUARE, "--target", "/dev/null", "--rerun", "off"], capsys)
    assert status == 1
    assert_one_line(err, "rov-mav run: error: cannot open /dev/null: ")
    assert files_under(workdir) == set()


def bad_outputs(work: Path) -> list[tuple[list[str], str, str]]:
    """(argv, option, reason) with outputs in a file's place, in a folder's place or under a file."""
    a_file = work.parent / "inputs" / "a_file"
    a_file.write_text("not a folder\n")
    a_folder = work.parent / "inputs"
    return [
        (["run", SQUARE, "--metrics", f"{a_file}/metrics.json"], "--metrics", f"{a_file} is not a folder"),
        (["run", SQUARE, "--metrics", str(a_folder)], "--metrics", "is a folder, expected a file name"),
        (["run", SQUARE, "--log", str(a_file)], "--log", "exists and is not a folder"),
        (["run", SQUARE, "--rerun", f"save:{a_file}/x/run.rrd"], "--rerun", f"{a_file} is not a folder"),
        (["simulate", SQUARE, "--out", str(a_file)], "--out", "exists and is not a folder"),
        (["simulate", SQUARE, "--metrics", ""], "--metrics", "empty path"),
        (["tune", SQUARE, "--out", f"{a_file}/gains.yaml"], "--out", f"{a_file} is not a folder"),
        (["tune", SQUARE, "--plot", f"{a_file}/plots"], "--plot", f"{a_file} is not a folder"),
    ]


@pytest.mark.parametrize("index", range(8))
def test_bad_output_paths(workdir, capsys, index):
    argv, option, reason = bad_outputs(workdir)[index]
    before = files_under(workdir.parent)
    status, err = rov_mav(argv, capsys)
    assert status == 2
    assert_one_line(err, f"rov-mav {argv[0]}: error: argument {option}: ", reason)
    assert files_under(workdir.parent) == before


def test_a_default_output_that_cannot_be_written_stops_before_any_work(workdir, capsys):
    """simulate's default folder out/simulate-square-fuzzy, where `out` is a file: refused before simulating."""
    (workdir / "out").write_text("a file where the output folder would go\n")
    status, err = rov_mav(["simulate", SQUARE], capsys)
    assert status == 2
    assert_one_line(err, "rov-mav simulate: error: --out out/simulate-square-fuzzy: out is not a folder")
    assert files_under(workdir) == {workdir / "out"}


def _drop_file_permission_override() -> None:
    """In the child, before exec: no CAP_DAC_OVERRIDE / CAP_DAC_READ_SEARCH, so that root too meets file modes."""
    libc = ctypes.CDLL(None, use_errno=True)
    for capability in (1, 2):                       # CAP_DAC_OVERRIDE, CAP_DAC_READ_SEARCH
        if libc.prctl(24, capability, 0, 0, 0) != 0:   # PR_CAPBSET_DROP
            raise OSError(ctypes.get_errno(), "prctl(PR_CAPBSET_DROP)")


def run_process(argv: list[str], cwd: Path) -> subprocess.CompletedProcess:
    """`rov-mav ARGV` as a process that file modes apply to (root's override dropped)."""
    return subprocess.run([sys.executable, "-m", "rov_mav.cli", *argv], cwd=cwd, capture_output=True, text=True,
                          timeout=120, preexec_fn=_drop_file_permission_override if os.geteuid() == 0 else None)


@pytest.mark.process
def test_unreadable_file_and_unwritable_folder_in_a_real_process(workdir):
    mission = workdir.parent / "inputs" / "locked.yaml"
    mission.write_text(Path(SQUARE).read_text())
    mission.chmod(0)
    locked = workdir.parent / "inputs" / "read_only"
    locked.mkdir()
    locked.chmod(0o555)
    try:
        unreadable = run_process(["simulate", str(mission)], workdir)
        unwritable = run_process(["simulate", SQUARE, "--out", str(locked / "figures")], workdir)
    finally:
        mission.chmod(0o644)
        locked.chmod(0o755)
    assert unreadable.returncode == 2
    assert_one_line(unreadable.stderr, f"rov-mav simulate: error: {mission}: cannot open: permission denied")
    assert unwritable.returncode == 2
    assert_one_line(unwritable.stderr, f"argument --out: {locked}/figures: cannot create anything in {locked}: "
                                       "permission denied")
    assert files_under(workdir) == set() and files_under(locked) == set()


@pytest.mark.process
def test_the_issue_cases_through_the_console_script(workdir):
    """As reported, as a user meets them: a PNG as --gains (read after the mission), --sysid 999 (refused by
    argparse); the other reported cases run in-process above."""
    picture = make_bad_file(workdir.parent / "inputs", "png")
    script = Path(sys.executable).with_name("rov-mav")
    for argv, expected in (
        (["run", SQUARE, "--gains", str(picture)], f"rov-mav run: error: {picture}: not a text YAML file (binary)"),
        (["run", SQUARE, "--sysid", "999"], "rov-mav run: error: argument --sysid: 999: expected an integer from 1 "
                                            "to 255"),
    ):
        proc = subprocess.run([str(script), *argv], cwd=workdir, capture_output=True, text=True, timeout=120)
        assert proc.returncode == 2, proc.stderr
        assert_one_line(proc.stderr, expected)
        assert proc.stdout == ""
    assert files_under(workdir) == set()


@pytest.mark.parametrize("command", sorted(cli.SUBCOMMANDS))
def test_every_help_page_renders_its_percent_signs(capsys, command):
    """`--help` formats argument help with %-substitution but descriptions only when they name %(prog)s: a page must
    show neither a doubled %% nor an unsubstituted %(...)s."""
    with pytest.raises(SystemExit) as ended:
        cli.main([command, "--help"])
    assert ended.value.code == 0
    page = capsys.readouterr().out
    assert f"rov-mav {command}" in page
    assert "%%" not in page and "%(" not in page
