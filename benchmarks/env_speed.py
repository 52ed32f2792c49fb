"""Environment steps per second on one core: physics only, and with a 96x96 egocentric image.

Prints one JSON object. Target: >= 3,000 steps/s with the image.
"""

from __future__ import annotations

import json
import os
import platform
import time

import cv2
import numpy as np

from inest_sim_node import EnvConfig, SweepToTopEnv


def steps_per_second(observation: str, steps: int = 6000) -> float:
    env = SweepToTopEnv(config=EnvConfig(observation=observation, view="ego", image_size=96, max_steps=100))
    actions = np.random.default_rng(0).uniform(-1, 1, size=(steps, 3))
    env.reset(seed=0)
    start = time.perf_counter()
    for action in actions:
        if env.step(action)[3]:
            env.reset()
    return steps / (time.perf_counter() - start)


def main() -> None:
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
    cv2.setNumThreads(1)
    steps_per_second("state", 500)  # warm-up
    result = {
        "benchmark": "env_speed",
        "physics_only_steps_per_s": round(max(steps_per_second("state") for _ in range(3))),
        "ego96_image_steps_per_s": round(max(steps_per_second("pixels") for _ in range(3))),
        "target_ego96_steps_per_s": 3000,
        "cores": 1,
        "python": platform.python_version(),
    }
    print(json.dumps(result))


if __name__ == "__main__":
    main()
