#!/usr/bin/python3
"""The stack configs derived from config/vslam.yaml agree with it.

    tests/launch/test_configs.py REPO_ROOT

config/vslam-one-camera.yaml (the one-camera robot) and
config/vslam-video-robot.yaml (recordings for the sensors) are copies of
config/vslam.yaml with a few stated differences; a value changed in
vslam.yaml and not in them would make them drift apart silently. Also: the
one-camera robot file has the two-camera one's forward camera and channels.
"""
import copy
import sys

import yaml


def load(root, name):
    with open(f"{root}/config/{name}", encoding="utf-8") as f:
        return yaml.safe_load(f)


def main():
    root = sys.argv[1]
    base = load(root, "vslam.yaml")
    failures = []

    def expect_same(name, derived, expected):
        if derived != expected:
            for key in sorted(set(derived) | set(expected)):
                if derived.get(key) != expected.get(key):
                    failures.append(f"{name}: '{key}' differs from vslam.yaml's: "
                                    f"{derived.get(key)!r} != {expected.get(key)!r}")

    # One camera: no backward front-end or driver, appearance on the forward
    # camera, the one-camera robot file.
    one = load(root, "vslam-one-camera.yaml")
    want = copy.deepcopy(base)
    want["robot"] = "robot/one_camera.yaml"
    del want["processes"]["frontend_backward"], want["processes"]["camera_backward"]
    want["processes"]["appearance"]["cameras"] = ["forward"]
    expect_same("vslam-one-camera.yaml", one, want)
    expect_same("vslam-one-camera.yaml processes", one["processes"], want["processes"])

    # Video robot: the cameras play recordings, the landmark map apart.
    video = load(root, "vslam-video-robot.yaml")
    want = copy.deepcopy(base)
    for cam in ("forward", "backward"):
        block = want["processes"][f"camera_{cam}"]
        block["source"] = f"video:../out/video-robot/{cam}.avi"
        block["speed"] = 1.0
    want["processes"]["landmark_db"]["map_file"] = "$XDG_DATA_HOME/vslam/video-robot.vslam-map"
    want["processes"]["appearance"]["map_file"] = (
        "$XDG_DATA_HOME/vslam/video-robot.vslam-appearance")
    expect_same("vslam-video-robot.yaml", video, want)
    expect_same("vslam-video-robot.yaml processes", video["processes"], want["processes"])

    two = load(root, "robot/sim_two_camera.yaml")
    one_robot = load(root, "robot/one_camera.yaml")
    if one_robot["channels"] != two["channels"]:
        failures.append("robot/one_camera.yaml: channels differ from sim_two_camera.yaml's")
    if one_robot["cameras"] != [c for c in two["cameras"] if c["name"] == "forward"]:
        failures.append("robot/one_camera.yaml: its camera is not sim_two_camera.yaml's forward one")

    for f in failures:
        print(f"FAIL: {f}")
    if failures:
        print("Update the derived files (their headers say how they differ) or this test.")
        return 1
    print("PASS: the derived stack configs agree with config/vslam.yaml")
    return 0


if __name__ == "__main__":
    sys.exit(main())
