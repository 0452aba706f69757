#!/usr/bin/env python3
"""Generates camgeom's ArUco dictionary tables, src/apriltag/families/aruco_*.rs.

Source: OpenCV's predefined dictionaries as OpenCV itself gives them
(`cv2.aruco.getPredefinedDictionary`: `markerSize`, `maxCorrectionBits`, and each marker's bits
drawn by `cv2.aruco.generateImageMarker` at one pixel a cell, checked against the bits of
`bytesList` through `Dictionary.getBitsFromByteList`). OpenCV's dictionaries are Apache 2
(OpenCV >= 4.5) data from the ArUco library (Garrido-Jurado et al. 2014, 2016).

One table is written per group of dictionaries that share codes: DICT_NxN_50, _100, _250 and
_1000 are, in OpenCV, the first 50, 100, 250 and 1000 markers of one list (checked here bit for
bit), so each group keeps the 1000 codes once and the four dictionaries are prefixes of it.
DICT_ARUCO_ORIGINAL (1024 markers, 5x5) and DICT_ARUCO_MIP_36h12 (250 markers, 6x6) stand
alone.

Layout: camgeom's decoder reads the payload cells in a layout built so that a quarter turn of
the marker is a cyclic shift of the code by nbits / 4 (src/apriltag/family.rs, AprilTag's
convention): the n x n payload is cut into four congruent blocks (quadrants for even n, a
pinwheel of n//2 x (n//2 + 1) blocks around the centre cell for odd n, the centre last), block
k + 1 being block k turned a quarter clockwise. Cell (x, y) is column x, row y counted from the
black border's outer corner, so OpenCV's bit (row r, column c) is cell (c + 1, r + 1), and the
marker's top-left corner (OpenCV's corner 0) is camgeom's tag coordinate (-1, -1).

Checks before anything is written:
  - the prefix property of each group;
  - turning the drawn marker a quarter turn is `rotate90` of its code (family.rs), every code;
  - the minimum Hamming distance over all codes and rotations of each dictionary, and that
    OpenCV's maxCorrectionBits is below half of it (so correction is unique at any
    errorCorrectionRate <= 1).

The chunk index: a read word with e <= maxCorrectionBits wrong bits agrees exactly with its code
on at least one of any e + 1 chunks (pigeonhole), so a dictionary group gets at least
maxCorrectionBits + 1 chunks (the largest of its dictionaries'); of those counts, the one with
the smallest flash (offsets `chunks (2^ceil(nbits/chunks) + 1)` u16 plus ids `chunks ncodes`
u16) is chosen.

Run from the repository root: python3 host-tests/scripts/make_aruco_dictionaries.py
(needs opencv-python >= 4.7 and numpy). `cargo test` never runs it.
"""
import os
import subprocess

import cv2
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
OUT = os.path.join(ROOT, "src", "apriltag", "families")

# (Rust module, [OpenCV dictionary names, smallest first])
GROUPS = [
    ("aruco_4x4", ["DICT_4X4_50", "DICT_4X4_100", "DICT_4X4_250", "DICT_4X4_1000"]),
    ("aruco_5x5", ["DICT_5X5_50", "DICT_5X5_100", "DICT_5X5_250", "DICT_5X5_1000"]),
    ("aruco_6x6", ["DICT_6X6_50", "DICT_6X6_100", "DICT_6X6_250", "DICT_6X6_1000"]),
    ("aruco_7x7", ["DICT_7X7_50", "DICT_7X7_100", "DICT_7X7_250", "DICT_7X7_1000"]),
    ("aruco_original", ["DICT_ARUCO_ORIGINAL"]),
    ("aruco_mip_36h12", ["DICT_ARUCO_MIP_36h12"]),
]


def rotate90(w, nbits):
    """family.rs's rotate90 (AprilTag's)."""
    p, l = nbits, 0
    if nbits % 4 == 1:
        p, l = nbits - 1, 1
    w = ((w >> l) << (p // 4 + l)) | (w >> (3 * p // 4 + l) << l) | (w & l)
    return w & ((1 << nbits) - 1)


def layout(n):
    """The payload cells (x, y), 1..=n, in decoding order (module docs)."""
    w = n + 2  # cells across the border's outer edge

    def cw(c):
        # A quarter turn clockwise on screen (y down): (x, y) -> (w - 1 - y, x).
        return (w - 1 - c[1], c[0])

    m = n // 2
    if n % 2 == 0:
        block = [(x, y) for y in range(1, m + 1) for x in range(1, m + 1)]
    else:
        block = [(x, y) for y in range(1, m + 1) for x in range(1, m + 2)]
    cells = list(block)
    for _ in range(3):
        block = [cw(c) for c in block]
        cells += block
    if n % 2 == 1:
        cells.append((m + 1, m + 1))
    assert sorted(cells) == sorted((x, y) for x in range(1, n + 1) for y in range(1, n + 1))
    return cells


def marker_bits(d, i):
    """OpenCV's drawn marker `i` at one pixel a cell, inside the border: n x n of 0/1."""
    n = d.markerSize
    img = cv2.aruco.generateImageMarker(d, i, n + 2, borderBits=1)
    assert (img[0, :] == 0).all() and (img[-1, :] == 0).all()
    assert (img[:, 0] == 0).all() and (img[:, -1] == 0).all()
    bits = (img[1:-1, 1:-1] > 127).astype(np.uint8)
    ref = cv2.aruco.Dictionary.getBitsFromByteList(d.bytesList[i : i + 1], n)
    assert (bits == ref).all(), i
    return bits


def encode(bits, cells):
    n = len(cells)
    code = 0
    for i, (x, y) in enumerate(cells):
        code |= int(bits[y - 1, x - 1]) << (n - 1 - i)
    return code


def popcount(a):
    a = a - ((a >> np.uint64(1)) & np.uint64(0x5555555555555555))
    a = (a & np.uint64(0x3333333333333333)) + ((a >> np.uint64(2)) & np.uint64(0x3333333333333333))
    a = (a + (a >> np.uint64(4))) & np.uint64(0x0F0F0F0F0F0F0F0F)
    return (a * np.uint64(0x0101010101010101)) >> np.uint64(56)


def min_distance(codes, n):
    """Smallest Hamming distance between two codes in any rotation, or a code and its own
    rotations."""
    rots = [list(codes)]
    for _ in range(3):
        rots.append([rotate90(c, n) for c in rots[-1]])
    base = np.array(codes, dtype=np.uint64)
    best = n
    for i in range(len(codes)):
        for k, r in enumerate(rots):
            x = popcount(base ^ np.uint64(r[i]))
            if k == 0:
                x[i] = n
            best = min(best, int(x.min()))
    return best


def index_bytes(nbits, ncodes, chunks):
    bits = -(-nbits // chunks)
    return 2 * chunks * ((1 << bits) + 1) + 2 * chunks * ncodes


def word(nbits):
    return "u16" if nbits <= 16 else "u32" if nbits <= 32 else "u64"


def group(module, names):
    dicts = [cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, nm)) for nm in names]
    n = dicts[0].markerSize
    assert all(d.markerSize == n for d in dicts)
    cells = layout(n)
    nbits = n * n
    big = dicts[-1]
    allbits = [marker_bits(big, i) for i in range(big.bytesList.shape[0])]
    codes = [encode(b, cells) for b in allbits]
    # Prefixes: the smaller dictionaries are the first markers of the largest, bit for bit.
    for d in dicts[:-1]:
        m = d.bytesList.shape[0]
        assert (d.bytesList == big.bytesList[:m]).all(), (names, m)
    # A quarter turn of the drawn marker is rotate90 of the code (either sense is a turn; the
    # layout is built with the sense the decoder uses, checked against AprilTag's layouts in
    # the Rust tests).
    for b, c in zip(allbits, codes):
        assert encode(np.rot90(b, 1), cells) == rotate90(c, nbits) or \
            encode(np.rot90(b, -1), cells) == rotate90(c, nbits)
    # Which sense: a clockwise turn (np.rot90 k=-1 on y-down rows) ...
    sense = "ccw" if encode(np.rot90(allbits[0], 1), cells) == rotate90(codes[0], nbits) else "cw"
    info = []
    for nm, d in zip(names, dicts):
        m = d.bytesList.shape[0]
        dist = min_distance(codes[:m], nbits)
        # Unique correction needs 2 maxCorrectionBits < dist; DICT_ARUCO_ORIGINAL breaks it
        # (distance 0: a marker equal to its own half turn), and camgeom then decodes as
        # OpenCV does (the smallest id within the bound), noted in the table.
        assert 2 * d.maxCorrectionBits < dist or nm == "DICT_ARUCO_ORIGINAL", (nm, dist)
        info.append((nm, m, d.maxCorrectionBits, dist))
    # Markers equal to one of their own turns: their corner order is not defined by the marker.
    symmetric = []
    for i, c in enumerate(codes):
        r = c
        for k in range(1, 4):
            r = rotate90(r, nbits)
            if r == c:
                symmetric.append((i, k))
                break
    need = max(mc for _, _, mc, _ in info) + 1
    chunks = min(range(need, 17), key=lambda c: (index_bytes(nbits, len(codes), c), c))
    return {
        "module": module, "n": n, "nbits": nbits, "cells": cells, "codes": codes,
        "info": info, "chunks": chunks, "sense": sense, "symmetric": symmetric,
        "flash": index_bytes(nbits, len(codes), chunks) + len(codes) * {"u16": 2, "u32": 4, "u64": 8}[word(nbits)],
    }


def rust(g):
    nbits, w = g["nbits"], word(g["nbits"])
    names = ", ".join(f"`{nm}`" for nm, *_ in g["info"])
    L = []
    L.append(f"//! {names}: generated by `host-tests/scripts/make_aruco_dictionaries.py`, do not edit.")
    L.append("//!")
    L.append(f"//! OpenCV {cv2.__version__}'s predefined dictionaries (`cv2.aruco.getPredefinedDictionary`,")
    L.append("//! Apache 2; the ArUco library's markers), each marker read from `generateImageMarker` and")
    L.append("//! checked against `bytesList`. Ids are OpenCV's; the codes are the markers' payload bits in")
    L.append("//! camgeom's layout (a quarter turn is a cyclic shift of the code, `super::super::family`).")
    if len(g["info"]) > 1:
        L.append("//! The dictionaries are prefixes of one list (checked bit for bit): one table serves all.")
    L.append("//!")
    L.append("//! | dictionary | markers | maxCorrectionBits | minimum distance (all rotations) |")
    L.append("//! |---|---|---|---|")
    for nm, m, mc, dist in g["info"]:
        L.append(f"//! | `{nm}` | {m} | {mc} | {dist} |")
    if any(2 * mc >= dist for _, _, mc, dist in g["info"]):
        L.append("//!")
        L.append("//! Below `2 maxCorrectionBits + 1` a read word can be within the bound of two codes:")
        L.append("//! it decodes to the smallest id, as OpenCV's `Dictionary::identify` does.")
    for i, k in g["symmetric"]:
        L.append(f"//! Marker {i} is its own {'half' if k == 2 else 'quarter'} turn: its corner order is not")
        L.append("//! defined by the marker (camgeom gives the smallest rotation; OpenCV's depends on where")
        L.append("//! its contour starts).")
    L.append("")
    L.append("use crate::apriltag::family::LayoutBit;")
    L.append("")
    L.append("/// Payload cells across (OpenCV's `markerSize`).")
    L.append(f"pub(crate) const MARKER_SIZE: u8 = {g['n']};")
    L.append("/// Chunks of the lookup index (at least the group's largest maxCorrectionBits + 1).")
    L.append(f"pub(crate) const CHUNKS: usize = {g['chunks']};")
    for nm, m, mc, dist in g["info"]:
        c = nm.upper()
        L.append(f"/// `{nm}`: markers, OpenCV's maxCorrectionBits, minimum distance.")
        L.append(f"pub(crate) const {c}: (usize, u8, u8) = ({m}, {mc}, {dist});")
    n = len(g["codes"])
    L.append("")
    L.append(f"/// The {n} codes (bit `nbits - 1 - i` is layout cell `i`, set when white), OpenCV's ids.")
    L.append(f"pub(crate) const CODES: [u64; {n}] = [")
    per = 8 if nbits <= 16 else 6 if nbits <= 32 else 4
    for i in range(0, n, per):
        L.append("    " + " ".join(f"0x{c:0{(nbits + 3) // 4}x}," for c in g["codes"][i : i + per]))
    L.append("];")
    L.append("")
    L.append(f"/// [`CODES`] as stored in flash, {w} each.")
    L.append(f"pub(crate) static STORED: [{w}; {n}] = super::narrow_{w}(&CODES);")
    L.append("")
    L.append("/// The cell `(x, y)` of each bit, counted from the black border's outer corner.")
    L.append(f"pub(crate) static LAYOUT: [LayoutBit; {nbits}] = [")
    for x, y in g["cells"]:
        L.append(f"    LayoutBit {{ x: {x}, y: {y} }},")
    L.append("];")
    L.append("")
    return "\n".join(L)


def main():
    for module, names in GROUPS:
        g = group(module, names)
        path = os.path.join(OUT, module + ".rs")
        with open(path, "w") as f:
            f.write(rust(g))
        subprocess.run(["rustfmt", "--edition", "2024", path], check=True)
        print(f"{module}: {len(g['codes'])} codes, {g['nbits']} bits, {g['chunks']} chunks, "
              f"rotate90 = {g['sense']} turn, flash {g['flash']} B; "
              + "; ".join(f"{nm} {m} max {mc} dist {dist}" for nm, m, mc, dist in g["info"]))


if __name__ == "__main__":
    main()
