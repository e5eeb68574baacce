"""ArduPilot's DataFlash log format (.BIN), written by our own encoder, for the built-in vehicle's on-board log.

A file is a sequence of records: 0xA3 0x95, a type id, then the fields packed little-endian with no padding
(`libraries/AP_Logger/LogStructure.h`). Each type is described once by an FMT record (type 128, 89 bytes: type,
length including the 3 header bytes, a 4-character name, a format string of one character per field, the
comma-separated labels) before its first record; FMTU records give each field's unit and multiplier (UNIT and MULT
records name them). Every data record's first field is TimeUS, microseconds since boot. The messages and their
layouts are ArduSub 4.7's (ArduPilot master of 2025: ATT in float degrees, BARO with AltAMSL, PARM with Default,
BAT with RemPct, H and SH); a reader must decode any file through its own FMT records (older ArduSub logs differ).
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass

HEADER = b"\xa3\x95"
FMT_TYPE = 128
# format character -> (struct code, scale applied before packing: stored = value * scale)
CODES = {"b": ("b", 1), "B": ("B", 1), "h": ("h", 1), "H": ("H", 1), "i": ("i", 1), "I": ("I", 1), "f": ("f", 1),
         "d": ("d", 1), "n": ("4s", 1), "N": ("16s", 1), "Z": ("64s", 1), "c": ("h", 100), "C": ("H", 100),
         "e": ("i", 100), "E": ("I", 100), "L": ("i", 10_000_000), "M": ("B", 1), "q": ("q", 1), "Q": ("Q", 1)}
UNITS = {"-": "", "?": "UNKNOWN", "s": "s", "#": "instance", "d": "deg", "h": "degheading", "k": "deg/s",
         "n": "m/s", "m": "m", "o": "m/s/s", "Y": "us", "P": "Pa", "O": "degC", "D": "deglatitude",
         "U": "deglongitude", "v": "V", "A": "A", "a": "Ah", "X": "W.h", "w": "Ohm", "%": "%"}
MULTIPLIERS = {"-": 0.0, "?": 1.0, "0": 1.0, "B": 1e-2, "C": 1e-3, "F": 1e-6, "G": 1e-7}


@dataclass(frozen=True)
class Format:
    """One message type: `LogStructure` entries as ArduPilot declares them (name, format, labels, units, mults)."""

    type: int
    name: str
    format: str
    labels: str
    units: str
    mults: str

    @property
    def struct(self) -> struct.Struct:
        return struct.Struct("<" + "".join(CODES[c][0] for c in self.format))

    @property
    def length(self) -> int:
        return 3 + self.struct.size


def _formats(*rows) -> dict[str, Format]:
    return {row[0]: Format(i, *row) for i, row in enumerate(rows, start=64)}


FMT = Format(FMT_TYPE, "FMT", "BBnNZ", "Type,Length,Name,Format,Columns", "-b---", "-----")
FORMATS = {"FMT": FMT, **_formats(
    ("UNIT", "QbZ", "TimeUS,Id,Label", "s--", "F--"),
    ("MULT", "Qbd", "TimeUS,Id,Mult", "s--", "F--"),
    ("FMTU", "QBNN", "TimeUS,FmtType,UnitIds,MultIds", "s---", "F---"),
    ("PARM", "QNff", "TimeUS,Name,Value,Default", "s---", "F---"),
    ("MSG", "QZ", "TimeUS,Message", "s-", "F-"),
    ("VER", "QBHBBBBIZH", "TimeUS,BT,BST,Maj,Min,Pat,FWT,GH,FWS,APJ", "s---------", "F---------"),
    ("MODE", "QMBB", "TimeUS,Mode,ModeNum,Rsn", "s---", "F---"),
    ("ARM", "QBIBB", "TimeUS,ArmState,ArmChecks,Forced,Method", "s----", "F----"),
    ("ATT", "QffffffB", "TimeUS,DesRoll,Roll,DesPitch,Pitch,DesYaw,Yaw,AEKF", "sddddhh-", "F000000-"),
    ("RATE", "Qfffffffffffff", "TimeUS,RDes,R,ROut,PDes,P,POut,YDes,Y,YOut,ADes,A,AOut,AOutSlew",
     "skk-kk-kk-oo--", "F?????????BB--"),
    ("RCIN", "Q" + "H" * 14, "TimeUS," + ",".join(f"C{i}" for i in range(1, 15)), "s" + "Y" * 14, "F" + "-" * 14),
    ("RCOU", "Q" + "H" * 14, "TimeUS," + ",".join(f"C{i}" for i in range(1, 15)), "s" + "Y" * 14, "F" + "-" * 14),
    ("CTUN", "Qffffffffffhh", "TimeUS,ThI,ABst,ThO,ThH,DAlt,Alt,BAlt,DSAlt,SAlt,TAlt,DCRt,CRt", "s----mmmmmmnn",
     "F----00B00BBB"),
    ("BARO", "QBfffcfIffB", "TimeUS,I,Alt,AltAMSL,Press,Temp,CRt,SMS,Offset,GndTemp,Health", "s#mmPOnsmO-",
     "F-000B0C?0-"),
    ("XKF1", "QBccCfffffffccce", "TimeUS,C,Roll,Pitch,Yaw,VN,VE,VD,dPD,PN,PE,PD,GX,GY,GZ,OH", "s#ddhnnnnmmmkkkm",
     "F-BBB0000000BBBB"),
    ("POS", "QLLfff", "TimeUS,Lat,Lng,Alt,RelHomeAlt,RelOriginAlt", "sDUmmm", "FGG000"),
    ("BAT", "QBfffffcfBBB", "TimeUS,Inst,Volt,VoltR,Curr,CurrTot,EnrgTot,Temp,Res,RemPct,H,SH", "s#vvAaXOw%-%",
     "F-000C0?0000"),
    # `RangeFinder::Log_RFND`, the 2025+ layout (Dist a float in m, Quality -1..100); 4.5 wrote Dist as uint16 cm
    # without Quality ("QBCBB"): the bridge writes this layout for both
    ("RFND", "QBfBBb", "TimeUS,Instance,Dist,Stat,Orient,Quality", "s#m--%", "F-0---"),
)}


def _field(code: str, value):
    fmt, scale = CODES[code]
    if fmt.endswith("s"):
        return str(value).encode()[:int(fmt[:-1])]
    if fmt in ("f", "d"):
        return float(value)
    number = float(value) * scale
    if not math.isfinite(number):
        number = 0.0
    low, high = _LIMITS[fmt]
    return min(max(int(round(number)), low), high)


_LIMITS = {"b": (-2 ** 7, 2 ** 7 - 1), "B": (0, 2 ** 8 - 1), "h": (-2 ** 15, 2 ** 15 - 1), "H": (0, 2 ** 16 - 1),
           "i": (-2 ** 31, 2 ** 31 - 1), "I": (0, 2 ** 32 - 1), "q": (-2 ** 63, 2 ** 63 - 1), "Q": (0, 2 ** 64 - 1)}


def record(fmt: Format, *values) -> bytes:
    """One record of `fmt` from its fields' values in their units (scaled here as the format letter says)."""
    if len(values) != len(fmt.format):
        raise ValueError(f"{fmt.name}: {len(values)} values for {len(fmt.format)} fields")
    return HEADER + bytes([fmt.type]) + fmt.struct.pack(*(_field(c, v) for c, v in zip(fmt.format, values)))


def header_records(time_us: int, params: list[tuple[str, float, float]], firmware: tuple[int, int, int],
                   firmware_string: str) -> bytes:
    """What ArduPilot writes as a file starts (`LoggerMessageWriter_DFLogStart`): FMT for every type (FMT's own
    first), PARM for every parameter (name, value, default), UNIT, MULT, FMTU, then the firmware MSG and VER. FMTU's
    TimeUS is the boot time, as ArduPilot's (pymavlink misreads an FMTU whose TimeUS is a small type id)."""
    out = [record(FMT, f.type, f.length, f.name, f.format, f.labels) for f in FORMATS.values()]
    out += [record(FORMATS["PARM"], time_us, name, value, default) for name, value, default in params]
    out += [record(FORMATS["UNIT"], time_us, ord(k), label) for k, label in UNITS.items()]
    out += [record(FORMATS["MULT"], time_us, ord(k), value) for k, value in MULTIPLIERS.items()]
    out += [record(FORMATS["FMTU"], max(time_us, 256), f.type, f.units, f.mults) for f in FORMATS.values()
            if f is not FMT]
    major, minor, patch = firmware
    out.append(record(FORMATS["MSG"], time_us, firmware_string))
    out.append(record(FORMATS["VER"], time_us, 3, 0, major, minor, patch, 255, 0, firmware_string, 0))  # SITL
    out.append(record(FORMATS["MSG"], time_us, "RC Protocol: None"))
    return b"".join(out)
