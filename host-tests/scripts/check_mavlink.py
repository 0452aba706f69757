#!/usr/bin/env python3
"""Reads a board's MAVLink stream with pymavlink (the autopilot side's reference parser) and
checks it against the board's own records.

    check_mavlink.py MAVLINK_BIN MONITOR_JSONL WIDTH HEIGHT

MAVLINK_BIN is what the board sent over its MAVLink UART (`cargo xtask run` saves the tag
job's as target/camgeom-run/tag/mavlink.bin); MONITOR_JSONL is `camgeom monitor --replay
serial.bin --json` of the same run (the frame records, poses to the bit); WIDTH x HEIGHT is the
target's size in metres. Checked, with pymavlink's MAVLink 2 parser (CRC and CRC_EXTRA
included):

- every byte parses: no bad CRC, no unknown message, nothing skipped;
- at least one HEARTBEAT (MAV_TYPE_CAMERA);
- one LANDING_TARGET per frame with a pose, in frame order, time_usec increasing;
- each: MAV_FRAME_BODY_FRD, position_valid = 1, type VISION_FIDUCIAL; with the target's centre
  c = R (w/2, h/2, 0) + t from the record's pose (Rodrigues vector r, translation t):
  distance = |c| and (x, y, z) = R_bc c within 1 mm, angle_x / angle_y the centre's offset
  from the optical axis, and q the rotation R_bc R (to 1e-4), where R_bc is the default
  mounting (camera looking down, top of the image toward the nose).

Prints one line and exits 0, or says what differs and exits 1. Needs pymavlink and numpy.
"""

import json
import math
import sys

import numpy as np
from pymavlink.dialects.v20 import common as mavlink2

# Body FRD from camera: camera x (right) -> body y, camera y (down the image) -> body -x,
# camera z (optical axis) -> body z (camgeom_fw_app::mavlink::MavlinkConfig::DOWNWARD_TOP_FORWARD).
R_BC = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
MM = 1e-3


def rodrigues(r):
    """Rotation matrix of the rotation vector r (axis times angle)."""
    r = np.asarray(r, dtype=float)
    theta = np.linalg.norm(r)
    if theta < 1e-12:
        return np.eye(3)
    k = r / theta
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(theta) * kx + (1 - math.cos(theta)) * kx @ kx


def quat_to_matrix(q):
    w, x, y, z = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def fail(msg):
    print(f"check_mavlink: {msg}")
    sys.exit(1)


def main():
    if len(sys.argv) != 5:
        fail("usage: check_mavlink.py MAVLINK_BIN MONITOR_JSONL WIDTH HEIGHT")
    path, jsonl = sys.argv[1], sys.argv[2]
    w, h = float(sys.argv[3]), float(sys.argv[4])
    data = open(path, "rb").read()
    parser = mavlink2.MAVLink(None)
    parser.robust_parsing = True
    msgs = []
    # Byte by byte, as a serial port delivers them.
    for b in data:
        m = parser.parse_char(bytes([b]))
        if m is not None:
            msgs.append(m)
    bad = [m for m in msgs if m.get_type() == "BAD_DATA"]
    if bad or parser.total_receive_errors:
        fail(f"{len(bad)} unparsable chunks, {parser.total_receive_errors} receive errors in {path}")
    if parser.total_bytes_received != len(data):
        fail(f"parsed {parser.total_bytes_received} of {len(data)} bytes")
    heartbeats = [m for m in msgs if m.get_type() == "HEARTBEAT"]
    targets = [m for m in msgs if m.get_type() == "LANDING_TARGET"]
    others = {m.get_type() for m in msgs} - {"HEARTBEAT", "LANDING_TARGET"}
    if others or not heartbeats:
        fail(f"{len(heartbeats)} heartbeats, other messages {sorted(others)}")
    if any(m.type != mavlink2.MAV_TYPE_CAMERA for m in heartbeats):
        fail("a HEARTBEAT that is not a camera's")
    frames = [json.loads(line) for line in open(jsonl) if line.strip()]
    posed = [f for f in frames if "frame" in f and f.get("pose") and not f.get("error")]
    if len(targets) != len(posed):
        fail(f"{len(targets)} LANDING_TARGET for {len(posed)} frames with a pose")
    worst = {"distance": 0.0, "xyz": 0.0, "angle": 0.0, "q": 0.0}
    last_time = -1
    for m, f in zip(targets, posed):
        if m.time_usec <= last_time:
            fail(f"frame {f['frame']}: time_usec {m.time_usec} not after {last_time}")
        last_time = m.time_usec
        if (m.frame, m.position_valid, m.type) != (
            mavlink2.MAV_FRAME_BODY_FRD,
            1,
            mavlink2.LANDING_TARGET_TYPE_VISION_FIDUCIAL,
        ):
            fail(f"frame {f['frame']}: frame {m.frame}, position_valid {m.position_valid}, type {m.type}")
        r = rodrigues(f["pose"]["rvec"])
        c = r @ np.array([w / 2, h / 2, 0.0]) + np.array(f["pose"]["t"], dtype=float)
        body = R_BC @ c
        worst["distance"] = max(worst["distance"], abs(m.distance - np.linalg.norm(c)))
        worst["xyz"] = max(worst["xyz"], float(np.max(np.abs(np.array([m.x, m.y, m.z]) - body))))
        worst["angle"] = max(
            worst["angle"],
            abs(m.angle_x - math.atan2(c[0], c[2])),
            abs(m.angle_y - math.atan2(c[1], c[2])),
        )
        worst["q"] = max(worst["q"], float(np.max(np.abs(quat_to_matrix(m.q) - R_BC @ r))))
    if worst["distance"] > MM or worst["xyz"] > MM or worst["angle"] > 1e-4 or worst["q"] > 1e-4:
        fail(f"off by {worst}")
    print(
        f"pymavlink reads {path}: {len(data)} bytes, {len(heartbeats)} HEARTBEAT, "
        f"{len(targets)} LANDING_TARGET = the {len(posed)} frames with a pose; worst |distance - |c|| "
        f"{worst['distance'] * 1e3:.4f} mm, x/y/z {worst['xyz'] * 1e3:.4f} mm, angles {worst['angle']:.1e} rad, "
        f"rotation {worst['q']:.1e}"
    )


if __name__ == "__main__":
    main()
