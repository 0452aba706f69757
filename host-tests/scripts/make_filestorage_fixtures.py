#!/usr/bin/env python3
"""Writes the OpenCV FileStorage fixtures in host-tests/data/fixtures/filestorage/.

Nothing here runs during `cargo test`: the outputs are committed, and
host-tests/tests/it/filestorage.rs reads the files with camgeom-host's FileStorage reader and
compares every node with the values this script recorded. Regenerate (from the repository
root) with

    pip install opencv-python-headless numpy
    python3 host-tests/scripts/make_filestorage_fixtures.py

and commit the changed files together with the OpenCV version the script prints.

Outputs:
  opencv.yml      written by cv2.FileStorage (YAML): scalars (integers, reals, strings, a string
                  that looks like a number), matrices of dt d, f, i and 3u (one long enough that
                  OpenCV wraps its data over many lines, one with NaN and infinities), a nested
                  mapping holding a matrix, a block sequence (scalars, a mapping, a matrix), a
                  flow sequence and a flow mapping (which OpenCV writes as `{ a:1, ... }`)
  opencv.xml      the same nodes written as XML, plus a matrix inside a flow mapping (OpenCV
                  reads that back from XML; its YAML writer puts a block mapping inside the flow
                  mapping, which OpenCV's own reader rejects, so the YAML file leaves it out)
  expected.json   {"opencv.yml": NODES, "opencv.xml": NODES}: NODES is a list of [key, node] in
                  file order; a node is {"int": n}, {"real": x} (x a number, or "nan", "inf",
                  "-inf"), {"string": s}, {"matrix": {"rows", "cols", "channels", "dt", "data"}},
                  {"map": NODES} or {"seq": [node, ...]}. Reals are Python floats (repr: the
                  shortest text that reads back to the same double); the data of a `dt: f`
                  matrix is each float32 widened exactly to a double.

The script reads every file back with cv2.FileStorage and checks that OpenCV itself gets the
recorded values, so the fixtures are files OpenCV both writes and reads.
"""

import json
import math
import os
import struct

import cv2
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.path.join(HERE, "..", "data", "fixtures", "filestorage")

DT = {np.float64: "d", np.float32: "f", np.int32: "i", np.uint8: "u"}


def real(x):
    x = float(x)
    if math.isnan(x):
        return "nan"
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    return x


def mat(m):
    m = np.asarray(m)
    channels = m.shape[2] if m.ndim == 3 else 1
    dt = DT[m.dtype.type]
    data = [real(v) if dt in "df" else int(v) for v in m.reshape(-1)]
    return {
        "matrix": {
            "rows": m.shape[0],
            "cols": m.shape[1],
            "channels": channels,
            "dt": dt if channels == 1 else f"{channels}{dt}",
            "data": data,
        }
    }


def nodes(rng, xml):
    """The fixture's nodes as [key, python value, expected node]: the same content for YAML and
    XML, except the matrix inside a flow mapping (XML only, see the module docs)."""
    camera_matrix = np.array(
        [[612.4182, 0.0, 318.2571], [0.0, 611.9033, 241.6128], [0.0, 0.0, 1.0]], dtype=np.float64
    )
    dist = np.array([[-0.27935, 0.10318, 0.00042, -0.00117, -0.01892]], dtype=np.float64)
    out = [
        ["count", ("int", 42)],
        ["offset", ("int", -7)],
        ["ratio", ("real", 0.1)],
        ["avogadro", ("real", 6.02214076e23)],
        ["tiny", ("real", 1.5e-300)],
        ["negative", ("real", -2.5)],
        ["name", ("string", "left camera")],
        ["looks_like_a_number", ("string", "42")],
        ["punctuation", ("string", "x: y # z, [w]")],
        ["camera_matrix", ("mat", camera_matrix)],
        ["distortion_coefficients", ("mat", dist)],
        ["float_matrix", ("mat", rng.normal(size=(4, 3)).astype(np.float32))],
        ["long_matrix", ("mat", rng.normal(scale=100.0, size=(12, 10)))],
        ["int_matrix", ("mat", np.array([[1, -2, 3], [-40000, 5, 2147483647]], dtype=np.int32))],
        ["rgb", ("mat", rng.integers(0, 256, size=(2, 3, 3)).astype(np.uint8))],
        ["special", ("mat", np.array([[np.nan, np.inf, -np.inf, 0.0]]))],
        [
            "nested",
            (
                "map",
                [
                    ["label", ("string", "inner")],
                    ["scale", ("real", 2.5)],
                    ["rvec", ("mat", np.array([[0.1], [-0.2], [0.3]]))],
                    ["deeper", ("map", [["k", ("int", 1)], ["s", ("string", "two words")]])],
                ],
            ),
        ],
        [
            "sequence",
            (
                "seq",
                [
                    ("int", 1),
                    ("real", 2.5),
                    ("string", "three"),
                    ("map", [["x", ("int", 4)], ["y", ("real", 5.5)]]),
                    ("mat", np.eye(2, dtype=np.float64)),
                ],
            ),
        ],
        ["flow_sequence", ("flowseq", [("int", 1), ("int", 2), ("real", 3.5)])],
        [
            "flow_mapping",
            (
                "flowmap",
                [["a", ("int", 1)], ["b", ("real", -0.25)], ["s", ("string", "two words")]],
            ),
        ],
    ]
    if xml:
        out.append(
            [
                "flow_mapping_with_matrix",
                ("flowmap", [["id", ("int", 3)], ["m", ("mat", np.array([[1.0, 2.0]]))]]),
            ]
        )
    return out


def write_node(fs, key, node):
    kind, value = node
    if kind in ("int", "real", "string", "mat"):
        fs.write(key, value)
    elif kind in ("map", "flowmap"):
        flags = cv2.FileNode_MAP | (cv2.FileNode_FLOW if kind == "flowmap" else 0)
        fs.startWriteStruct(key, flags)
        for k, v in value:
            write_node(fs, k, v)
        fs.endWriteStruct()
    else:
        flags = cv2.FileNode_SEQ | (cv2.FileNode_FLOW if kind == "flowseq" else 0)
        fs.startWriteStruct(key, flags)
        for v in value:
            write_node(fs, "", v)
        fs.endWriteStruct()


def expected(node):
    kind, value = node
    if kind == "int":
        return {"int": value}
    if kind == "real":
        return {"real": real(value)}
    if kind == "string":
        return {"string": value}
    if kind == "mat":
        return mat(value)
    if kind in ("map", "flowmap"):
        return {"map": [[k, expected(v)] for k, v in value]}
    return {"seq": [expected(v) for v in value]}


def same_real(a, b):
    """Bit-identical doubles (any NaN equals any NaN)."""
    a, b = float(a), float(b)
    return (math.isnan(a) and math.isnan(b)) or struct.pack("<d", a) == struct.pack("<d", b)


def check(fn, node, where):
    """OpenCV's own reading of FileNode `fn` must give back what was written."""
    kind, value = node
    if kind == "int":
        assert fn.isInt() and int(fn.real()) == value, where
    elif kind == "real":
        assert fn.isReal() and same_real(fn.real(), value), where
    elif kind == "string":
        assert fn.isString() and fn.string() == value, where
    elif kind == "mat":
        m = fn.mat()
        assert m.dtype == value.dtype and m.shape == value.shape, where
        assert all(same_real(float(a), float(b)) for a, b in zip(m.reshape(-1), value.reshape(-1))), where
    elif kind in ("map", "flowmap"):
        assert fn.isMap() and fn.size() == len(value), where
        for k, v in value:
            check(fn.getNode(k), v, f"{where}.{k}")
    else:
        assert fn.isSeq() and fn.size() == len(value), where
        for i, v in enumerate(value):
            check(fn.at(i), v, f"{where}[{i}]")


def main():
    os.makedirs(OUT, exist_ok=True)
    record = {}
    for name in ["opencv.yml", "opencv.xml"]:
        # The same seed for both files: the same random matrices.
        content = nodes(np.random.default_rng(2024), name.endswith(".xml"))
        path = os.path.join(OUT, name)
        fs = cv2.FileStorage(path, cv2.FILE_STORAGE_WRITE)
        for key, node in content:
            write_node(fs, key, node)
        fs.release()
        fs = cv2.FileStorage(path, cv2.FILE_STORAGE_READ)
        for key, node in content:
            check(fs.getNode(key), node, f"{name}:{key}")
        fs.release()
        record[name] = [[key, expected(node)] for key, node in content]
    with open(os.path.join(OUT, "expected.json"), "w") as f:
        json.dump(record, f, indent=1)
        f.write("\n")
    print(f"OpenCV {cv2.__version__}, numpy {np.__version__}: wrote {os.path.relpath(OUT)}")


if __name__ == "__main__":
    main()
