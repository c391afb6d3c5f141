"""Run one of LeRobot's command-line tools (the ``main()`` its console script calls) with every
observation and action of the ``so101_sim`` robot logged to a JSON file, for tests to check
what the tool did to the simulated arm:

    python cli_probe.py LOG.json lerobot_replay --robot.type=so101_sim ...

The log holds, per ``get_observation()``: the simulated time and the joint positions, and the
shape, dtype and mean of each camera frame; per ``send_action()``: the goals sent.
"""

from __future__ import annotations

import atexit
import importlib
import json
import sys
from typing import Any

from lerobot_robot_so101sim import SO101Sim

LOG: dict[str, list[Any]] = {"observations": [], "actions": []}


def _describe(value: Any) -> Any:
    if getattr(value, "ndim", 0):
        return {"shape": list(value.shape), "dtype": str(value.dtype), "mean": float(value.mean())}
    return float(value)


def _install() -> None:
    get_observation, send_action = SO101Sim.get_observation, SO101Sim.send_action

    def logged_observation(self: SO101Sim) -> dict[str, Any]:
        obs = get_observation(self)
        entry = {k: _describe(v) for k, v in obs.items()}
        entry["time"] = self.time
        LOG["observations"].append(entry)
        return obs

    def logged_action(self: SO101Sim, action: dict[str, Any]) -> dict[str, Any]:
        sent = send_action(self, action)
        LOG["actions"].append({k: float(v) for k, v in sent.items()})
        return sent

    SO101Sim.get_observation = logged_observation  # type: ignore[method-assign]
    SO101Sim.send_action = logged_action  # type: ignore[method-assign]


def _dump(path: str) -> None:
    with open(path, "w") as f:
        json.dump(LOG, f)


def main() -> None:
    path, script, *args = sys.argv[1:]
    _install()
    atexit.register(_dump, path)
    sys.argv = [script.replace("_", "-"), *args]
    importlib.import_module(f"lerobot.scripts.{script}").main()


if __name__ == "__main__":
    main()
