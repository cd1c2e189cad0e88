"""Write the corpus of broken servo logs that tests/test_identify.py feeds to ``gearctl identify``.

Each file breaks one rule of the log format (gearctl/identify.py, ``read_log``) or of what identification
needs (a motor that moves and turns back, a load that crosses the gap). Run from anywhere:

    python tests/data/logs/make_corpus.py
"""

from __future__ import annotations

import math
from pathlib import Path

HERE = Path(__file__).resolve().parent
HEADER = "t,torque,theta1,theta2"


def rows(n: int, *, theta1=lambda t: 0.1 * math.sin(2 * math.pi * t), theta2=None, dt: float = 1e-3) -> list[str]:
    """``n`` rows of a smooth motion (a 1 Hz sine of the motor), load following through a gear of 4."""
    out = []
    for k in range(n):
        t = k * dt
        a = theta1(t)
        b = a / 4 if theta2 is None else theta2(t)
        out.append(f"{t:.6g},{0.01 * math.cos(2 * math.pi * t):.6g},{a:.9g},{b:.9g}")
    return out


def write(name: str, lines: list[str] | bytes) -> None:
    path = HERE / name
    if isinstance(lines, bytes):
        path.write_bytes(lines)
    else:
        path.write_text("\n".join(lines) + "\n")


def main() -> None:
    good = rows(12)
    no_theta1 = [",".join(r.split(",")[:2] + r.split(",")[3:]) for r in good]
    write("missing_column.csv", ["# theta1 is missing", "t,torque,theta2"] + no_theta1)
    write("duplicate_column.csv", ["t,torque,theta1,theta1"] + good)
    bad = list(good)
    bad[6] = "0.004," + bad[6].split(",", 1)[1]  # time goes back at the 7th sample (line 8)
    write("nonmonotonic.csv", [HEADER] + bad)
    write("uneven.csv", [HEADER] + good[:5] + good[6:])  # one sample missing: a 2 ms step (line 7)
    bad = list(good)
    bad[3] = bad[3].split(",")[0] + ",nan," + ",".join(bad[3].split(",")[2:])
    write("nan.csv", ["# torque is NaN on line 6", HEADER] + bad)
    bad = list(good)
    bad[4] = ",".join(bad[4].split(",")[:2] + ["inf"] + bad[4].split(",")[3:])
    write("inf.csv", [HEADER] + bad)
    bad = list(good)
    bad[2] = ",".join(bad[2].split(",")[:3] + ["abc"])
    write("text.csv", [HEADER] + bad)
    bad = list(good)
    bad[5] = ",".join(bad[5].split(",")[:3])
    write("ragged.csv", [HEADER] + bad)
    write("short.csv", [HEADER] + rows(100))
    write("slow_period.csv", [HEADER] + rows(12, dt=2.0))  # 2 s between samples: not a servo log
    write("no_header.csv", ["# a log with comments only", "# and no header row"])
    write("empty.csv", b"")
    write("binary.csv", HEADER.encode() + b"\n0,0,0,0\n0.001,0\x00\x01,0,0\n")
    write("latin1.csv", ("# caf\u00e9 (written in Latin-1)\n" + HEADER + "\n").encode("latin-1") + b"0,0,0,0\n")
    # format fine, but nothing to identify
    write("flat.csv", [HEADER] + rows(600, theta1=lambda t: 0.0))
    write("no_reversal.csv", [HEADER] + rows(600, theta1=lambda t: 0.5 * t))
    write("no_gap_crossing.csv", [HEADER] + rows(600, theta2=lambda t: 0.1 * math.sin(2 * math.pi * t) / 4))
    # the load crosses the gap each half period but always lies on the flank the motor's torque pulls away from
    # (the torque is that of the 1 Hz sine on shing1993_servo's inertia, 8.46e-4 kg m^2): no rest on either flank
    rest = ["t,torque,theta1,theta2"]
    for k in range(3000):
        t = k * 1e-3
        a = 0.1 * math.sin(2 * math.pi * t)
        u = -8.46e-4 * 0.1 * (2 * math.pi) ** 2 * math.sin(2 * math.pi * t)
        s = 5e-5 * math.tanh(50 * math.sin(2 * math.pi * t))
        rest.append(f"{t:.6g},{u:.6g},{a:.9g},{a / 4 - s / 0.075175:.9g}")
    write("no_rest.csv", rest)


if __name__ == "__main__":
    main()
