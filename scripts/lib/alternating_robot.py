"""A robot file whose cameras take turns (docs/camera.md, "Alternating
acquisition"): camera i gets alternate: {slot: i, slots: N}; calibration
paths are made absolute so the copy can live anywhere.

    /usr/bin/python3 scripts/lib/alternating_robot.py SRC.yaml DST.yaml
"""

import os
import sys

import yaml


def write_alternating_robot(src, dst):
    robot = yaml.safe_load(open(src))
    cams = robot["cameras"]
    for i, cam in enumerate(cams):
        cam["calibration"] = os.path.normpath(os.path.join(os.path.dirname(src),
                                                           cam["calibration"]))
        cam["alternate"] = {"slot": i, "slots": len(cams)}
    robot["name"] = robot["name"] + "_alternating"
    with open(dst, "w") as f:
        yaml.safe_dump(robot, f, sort_keys=False)


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    write_alternating_robot(sys.argv[1], sys.argv[2])
