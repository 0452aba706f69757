#!/usr/bin/env python3
"""OpenCV's ChArUco board layouts, for the layout test of camgeom::charuco::CharucoBoard.

    python3 host-tests/scripts/charuco_layout.py > host-tests/data/charuco/layout.csv

Rows `board,kind,id,k,x,y` for `cv2.aruco.CharucoBoard((X, Y), 0.04, 0.03, DICT_4X4_50)` with
(X, Y) in (5, 4), (6, 5), (4, 7), (11, 8): kind `marker` (id = the marker id of
`getIds()`, k = corner 0..3 of `getObjPoints()`) and kind `corner` (id = ChArUco corner id,
`getChessboardCorners()`, k = 0); x, y in metres. OpenCV's default (non-legacy) pattern.
"""
import cv2

d = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50)
print("board,kind,id,k,x,y")
for X, Y in [(5, 4), (6, 5), (4, 7), (11, 8)]:
    b = cv2.aruco.CharucoBoard((X, Y), 0.04, 0.03, d)
    assert not b.getLegacyPattern()
    for mid, obj in zip(b.getIds().ravel(), b.getObjPoints()):
        for k, p in enumerate(obj.reshape(-1, 3)):
            print("%dx%d,marker,%d,%d,%.6f,%.6f" % (X, Y, mid, k, p[0], p[1]))
    for i, p in enumerate(b.getChessboardCorners()):
        print("%dx%d,corner,%d,0,%.6f,%.6f" % (X, Y, i, p[0], p[1]))
