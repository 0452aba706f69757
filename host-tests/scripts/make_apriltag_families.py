#!/usr/bin/env python3
"""Generates camgeom's AprilTag family tables, src/apriltag/families/*.rs.

Source: the family definitions compiled into the AprilTag 3 C library (AprilRobotics/apriltag,
BSD 2-clause; the build that pip's `pupil-apriltags` ships, libapriltag 3.1), read through
ctypes from the library's own `tagXXX_create()`: the codes (`codes[]`, AprilTag 3's bit order,
most significant bit = bit 0 of the layout), the bit layout (`bit_x[]`, `bit_y[]`, in cells
from the black border's outer corner), `width_at_border`, `total_width`, `reversed_border` and
the minimum Hamming distance `h`.

Checks before anything is written:
  - tag36h11 id 0 is 0xd7e00984b, as in AprilTag's tag36h11.c;
  - for tag36h11, tag25h9 and tag16h5 every id, rendered from the code through the layout (as
    AprilTag's apriltag_to_image draws it: bit i white when set, at row bit_y[i], column
    bit_x[i]), is bit for bit OpenCV's marker (cv2.aruco DICT_APRILTAG_36h11 / 25h9 / 16h5,
    the bits of generateImageMarker inside the black border) turned by 180 degrees: the same
    ids, but OpenCV's upright marker is AprilTag's upside down, so a corner order read off an
    OpenCV-drawn marker is AprilTag's shifted by two;
  - rotating a tag image by 90 deg clockwise is the rotation AprilTag's decoder applies to a
    code (rotate90 in apriltag.c), for every code of every family: the layouts are built so;
  - the minimum Hamming distance over all codes and all their rotations is `h`.

Run from the repository root: python3 host-tests/scripts/make_apriltag_families.py
(needs `pip install pupil-apriltags opencv-python-headless numpy`). `cargo test` never runs it.
"""
import ctypes
import os
import subprocess

import cv2
import numpy as np
import pupil_apriltags
from pupil_apriltags.bindings import _ApriltagFamily

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
OUT = os.path.join(ROOT, "src", "apriltag", "families")

# (AprilTag name, Rust module, OpenCV dictionary or None)
FAMILIES = [
    ("tag36h11", "tag36h11", cv2.aruco.DICT_APRILTAG_36h11),
    ("tag25h9", "tag25h9", cv2.aruco.DICT_APRILTAG_25h9),
    ("tag16h5", "tag16h5", cv2.aruco.DICT_APRILTAG_16h5),
    ("tagStandard41h12", "tag_standard41h12", None),
]


def library():
    base = os.path.join(os.path.dirname(pupil_apriltags.__file__))
    for sub in ("lib", "lib64"):
        d = os.path.join(base, sub)
        if os.path.isdir(d):
            for f in sorted(os.listdir(d)):
                if f.startswith("libapriltag") and ".so" in f:
                    return ctypes.CDLL(os.path.join(d, f))
    raise RuntimeError("libapriltag not found in pupil_apriltags")


def signed(v):
    return v - (1 << 32) if v >= 1 << 31 else v


def read_family(lib, name):
    create = getattr(lib, name + "_create")
    create.restype = ctypes.POINTER(_ApriltagFamily)
    f = create().contents
    n, nbits = f.ncodes, f.nbits
    return {
        "codes": [f.codes[i] for i in range(n)],
        # uint32 in the struct, but the cells of tagStandard41h12 reach outside the border (-2).
        "bits": [(signed(f.bit_x[i]), signed(f.bit_y[i])) for i in range(nbits)],
        "nbits": nbits,
        "width_at_border": f.width_at_border,
        "total_width": f.total_width,
        "reversed_border": bool(f.reversed_border),
        "h": f.h,
    }


def rotate90(w, nbits):
    """apriltag.c's rotate90."""
    p, l = nbits, 0
    if nbits % 4 == 1:
        p, l = nbits - 1, 1
    w = ((w >> l) << (p // 4 + l)) | (w >> (3 * p // 4 + l) << l) | (w & l)
    return w & ((1 << nbits) - 1)


def render(fam, code):
    """The cells of a code: grid[y][x] = 1 (white) for the layout's cells, -1 elsewhere."""
    n = fam["nbits"]
    lo = min(min(x, y) for x, y in fam["bits"])
    hi = max(max(x, y) for x, y in fam["bits"])
    size = hi - lo + 1
    g = -np.ones((size, size), dtype=int)
    for i, (x, y) in enumerate(fam["bits"]):
        g[y - lo, x - lo] = (code >> (n - 1 - i)) & 1
    return g, lo


def popcount(a):
    a = a - ((a >> np.uint64(1)) & np.uint64(0x5555555555555555))
    a = (a & np.uint64(0x3333333333333333)) + ((a >> np.uint64(2)) & np.uint64(0x3333333333333333))
    a = (a + (a >> np.uint64(4))) & np.uint64(0x0F0F0F0F0F0F0F0F)
    return (a * np.uint64(0x0101010101010101)) >> np.uint64(56)


def min_distance(codes, n):
    """Smallest Hamming distance between two codes in any rotation, or a code and its own
    rotations (what 2-bit correction must stay below half of)."""
    rots = [list(codes)]
    for _ in range(3):
        rots.append([rotate90(c, n) for c in rots[-1]])
    base = np.array(codes, dtype=np.uint64)
    best = n
    for i, c in enumerate(codes):
        for k, r in enumerate(rots):
            x = popcount(base ^ np.uint64(r[i]))
            if k == 0:
                x[i] = n  # a code against itself
            best = min(best, int(x.min()))
    return best


def check(name, fam, cvdict):
    codes, n = fam["codes"], fam["nbits"]
    if name == "tag36h11":
        assert codes[0] == 0xD7E00984B, hex(codes[0])
    # A 90-degree clockwise turn of the image is rotate90 of the code (the decoder's search).
    for c in codes:
        g, _ = render(fam, c)
        rg, _ = render(fam, rotate90(c, n))
        # Cells outside the layout stay -1 in both; np.rot90(k=-1) turns clockwise (y down).
        assert (np.rot90(g, k=-1) == rg).all() or (np.rot90(g, k=1) == rg).all()
    dist = min_distance(codes, n)
    assert dist >= fam["h"], (name, dist, fam["h"])
    if cvdict is not None:
        d = cv2.aruco.getPredefinedDictionary(cvdict)
        assert d.bytesList.shape[0] == len(codes), (name, d.bytesList.shape)
        ms = d.markerSize
        for i, c in enumerate(codes):
            bits = cv2.aruco.Dictionary.getBitsFromByteList(d.bytesList[i : i + 1], ms)
            g, lo = render(fam, c)
            assert lo == 1 and g.shape == (ms, ms), (name, lo, g.shape)
            # OpenCV draws AprilTag's tag images turned by 180 degrees.
            assert (np.rot90(g, 2) == bits).all(), (name, i)
    return dist


def rust(name, module, fam, dist, cv):
    lines = []
    lines.append(f"//! `{name}`: generated by `host-tests/scripts/make_apriltag_families.py`, do not edit.")
    lines.append("//!")
    lines.append("//! The codes and the bit layout of AprilTag 3's family definition (AprilRobotics/apriltag,")
    lines.append("//! BSD 2-clause), read from the library itself.")
    if cv:
        lines.append(f"//! Verified bit for bit against OpenCV's `cv2.aruco` dictionary `{cv}`: every id is the")
        lines.append("//! same marker, which OpenCV draws turned by 180 degrees.")
    else:
        lines.append("//! OpenCV has no dictionary for this family; the host tests detect tags rendered from")
        lines.append("//! this table with AprilTag 3.")
    lines.append(f"//! Minimum Hamming distance over all codes and rotations: {dist}.")
    lines.append("")
    lines.append("use crate::apriltag::family::LayoutBit;")
    lines.append("")
    lines.append(f"/// The family's name in AprilTag.")
    lines.append(f"pub(crate) const NAME: &str = \"{name}\";")
    lines.append(f"/// Minimum Hamming distance between two codes (any rotation), as the family states it.")
    lines.append(f"pub(crate) const MIN_DISTANCE: u8 = {fam['h']};")
    lines.append(f"/// Cells across the detection border (its outer edge).")
    lines.append(f"pub(crate) const WIDTH_AT_BORDER: u8 = {fam['width_at_border']};")
    lines.append(f"/// Cells across the whole tag, white quiet zone included.")
    lines.append(f"pub(crate) const TOTAL_WIDTH: u8 = {fam['total_width']};")
    lines.append(f"/// `true` when the detection border is white inside black.")
    lines.append(f"pub(crate) const REVERSED_BORDER: bool = {'true' if fam['reversed_border'] else 'false'};")
    lines.append("")
    n = len(fam["codes"])
    lines.append(f"/// The {n} codes, AprilTag's bit order (bit `nbits - 1 - i` is layout cell `i`).")
    lines.append(f"pub(crate) static CODES: [u64; {n}] = [")
    for i in range(0, n, 4):
        lines.append("    " + " ".join(f"0x{c:0{(fam['nbits'] + 3) // 4}x}," for c in fam["codes"][i : i + 4]))
    lines.append("];")
    lines.append("")
    lines.append("/// The cell `(x, y)` of each bit, counted from the detection border's outer corner.")
    lines.append(f"pub(crate) static LAYOUT: [LayoutBit; {fam['nbits']}] = [")
    for x, y in fam["bits"]:
        lines.append(f"    LayoutBit {{ x: {x}, y: {y} }},")
    lines.append("];")
    lines.append("")
    return "\n".join(lines)


def main():
    lib = library()
    os.makedirs(OUT, exist_ok=True)
    cvnames = {
        cv2.aruco.DICT_APRILTAG_36h11: "DICT_APRILTAG_36h11",
        cv2.aruco.DICT_APRILTAG_25h9: "DICT_APRILTAG_25h9",
        cv2.aruco.DICT_APRILTAG_16h5: "DICT_APRILTAG_16h5",
    }
    for name, module, cvd in FAMILIES:
        fam = read_family(lib, name)
        dist = check(name, fam, cvd)
        path = os.path.join(OUT, module + ".rs")
        with open(path, "w") as f:
            f.write(rust(name, module, fam, dist, cvnames.get(cvd)))
        # The committed file is what `cargo fmt` leaves.
        subprocess.run(["rustfmt", "--edition", "2024", path], check=True)
        print(
            f"{name}: {len(fam['codes'])} codes, {fam['nbits']} bits, h={fam['h']} "
            f"(measured {dist}), width_at_border {fam['width_at_border']}, total_width "
            f"{fam['total_width']}, reversed {fam['reversed_border']} -> {os.path.relpath(path, ROOT)}"
        )


if __name__ == "__main__":
    main()
