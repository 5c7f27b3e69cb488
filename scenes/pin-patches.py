#!/usr/bin/env python3
"""Writes `pin.bpt`: a bowling pin as 12 uniform cubic B-spline patches (4 around x 3 up).

The surface is a revolved B-spline: a periodic ring of 4 control points (radius R at 0,
90, 180 and 270 degrees) swept along a profile of 6 control rows (height y, radius r),
the last row the mirror of the fourth through the axis point at the top, so that the
surface closes smoothly at its tip; the base is open (the pin stands on it). Patch
(i, j) takes rows j..j+3 and ring points i..i+3 (mod 4); u runs around the pin (against
the angle, so that dP/du x dP/dv faces outward), v up it. A ring of 4 uniform B-spline
points is not a circle: its radius is 0.667 R at the control points' angles and 0.648 R
between them, so R is the profile's r over 0.6575 (within 1.5 %).
Run: python3 scenes/pin-patches.py > scenes/pin.bpt
"""
import math

PROFILE = [(-0.62, 0.10), (0.02, 0.27), (0.62, 0.01), (0.90, 0.165), (1.0, 0.0)]
PROFILE.append((2 * PROFILE[4][0] - PROFILE[3][0], -PROFILE[3][1]))
RING = 4
ROUND = 0.6575


def point(row, k):
    y, r = PROFILE[row]
    a = 2 * math.pi * (k % RING) / RING
    R = r / ROUND
    return (R * math.cos(a), y, -R * math.sin(a))


patches = []
for j in range(len(PROFILE) - 3):
    for i in range(RING):
        patches.append([point(j + row, i + col) for row in range(4) for col in range(4)])
print(len(patches))
for p in patches:
    print("3 3")
    for q in p:
        print(" ".join(f"{round(c, 9) + 0.0:.9g}" for c in q))
