"""The lab motion written once, for the real SO-101 (through LeRobot) and for the simulation.

    (in the folder the examples were copied to: so101sim examples FOLDER; cd FOLDER)
    python hardware_style.py                      # simulated arm (real time)
    python hardware_style.py --viewer             # ... and watch it
    python hardware_style.py --robot real --port /dev/ttyACM0 --id my_follower

Only ``make_robot`` knows which arm it drives; everything after it is the same code.
"""

from __future__ import annotations

import argparse
import sys

from so101sim.robot.helpers import hold_robot, move_robot_to
from so101sim.units import STARTING_POSE, ZERO_POSE, format_pose


def make_robot(args: argparse.Namespace):
    if args.robot == "sim":
        from so101sim.robot import SO101SimFollower, SO101SimFollowerConfig

        return SO101SimFollower(
            SO101SimFollowerConfig(id=args.id, viewer=args.viewer, mode=args.mode)
        )
    if not args.port:
        sys.exit("--robot real needs --port (the follower's serial port, e.g. /dev/ttyACM0)")
    try:  # lerobot >= 0.4.3; older releases name the package so101_follower
        from lerobot.robots.so_follower import SO101Follower, SO101FollowerConfig
    except ImportError:
        try:
            from lerobot.robots.so101_follower import SO101Follower, SO101FollowerConfig
        except ImportError:
            sys.exit(
                "lerobot is not installed: `pip install 'lerobot[feetech]'` to drive the real "
                "arm (the simulation does not need it: use --robot sim)"
            )
    return SO101Follower(SO101FollowerConfig(port=args.port, id=args.id))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", choices=("sim", "real"), default="sim")
    parser.add_argument("--port", help="follower's serial port (real arm only)")
    parser.add_argument("--id", default="my_follower", help="arm id (LeRobot calibration name)")
    parser.add_argument("--viewer", action="store_true", help="sim: show MuJoCo's viewer")
    parser.add_argument("--mode", choices=("realtime", "lockstep"), default="realtime")
    args = parser.parse_args()

    robot = make_robot(args)
    robot.connect()
    try:
        print("start  :", format_pose(robot.get_observation()))
        move_robot_to(robot, ZERO_POSE, 2.0)
        hold_robot(robot, 2.0)
        print("zeros  :", format_pose(robot.get_observation()))
        move_robot_to(robot, STARTING_POSE, 2.0)
        hold_robot(robot, 1.0)
        print("back   :", format_pose(robot.get_observation()))
    finally:
        robot.disconnect()


if __name__ == "__main__":
    main()
