"""Readers of the files slam-rs writes (map_server PGM + YAML, TUM trajectories), written
from the formats' descriptions, for the checks of `cargo xtask eval ros2`."""

import math
import re


def read_pgm(path):
    """A binary PGM (P5, maxval < 256): width, height and the rows top first (bytes)."""
    data = open(path, "rb").read()
    tokens, pos = [], 0
    while len(tokens) < 4:
        while data[pos : pos + 1].isspace():
            pos += 1
        if data[pos : pos + 1] == b"#":
            pos = data.index(b"\n", pos) + 1
            continue
        end = pos
        while not data[end : end + 1].isspace():
            end += 1
        tokens.append(data[pos:end])
        pos = end
    assert tokens[0] == b"P5", f"{path}: not a binary PGM"
    w, h, maxval = int(tokens[1]), int(tokens[2]), int(tokens[3])
    assert maxval < 256
    pixels = data[pos + 1 : pos + 1 + w * h]
    assert len(pixels) == w * h, f"{path}: {len(pixels)} pixels, expected {w}x{h}"
    return w, h, pixels


def read_map_yaml(path):
    """resolution (m/cell) and origin [x, y, yaw] of a map_server YAML."""
    text = open(path).read()
    res = float(re.search(r"resolution:\s*([-\d.e+]+)", text).group(1))
    origin = [float(x) for x in re.search(r"origin:\s*\[([^\]]*)\]", text).group(1).split(",")]
    return res, origin


def read_tum(path):
    """(t, x, y, yaw) of each line of a TUM trajectory (yaw of a z-axis quaternion)."""
    out = []
    for line in open(path):
        if line.startswith("#") or not line.strip():
            continue
        v = [float(x) for x in line.split()]
        out.append((v[0], v[1], v[2], 2.0 * math.atan2(v[6], v[7])))
    return out


def trinary(v):
    """map_saver's pixel of an occupancy value (percent, -1 unknown): occupied (≥ 65) 0,
    free (0–25) 254, else 205."""
    if v >= 65:
        return 0
    if 0 <= v <= 25:
        return 254
    return 205
