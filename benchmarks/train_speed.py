"""SAC training speed with the environment's reward and with the INEST reward, same settings.

Prints one JSON object. Target: INEST >= 0.8x the env-reward speed (the encoder
must not be the bottleneck). Needs a reward model: `train_speed.py [MODEL_FOLDER]`
(default: the committed default model, runtime.model.DEFAULT_MODEL), optionally
followed by the torch thread count (default: the training config's).
"""

from __future__ import annotations

import json
import sys
import tempfile
import time
from typing import Any

import numpy as np
import torch
from inest_agent_node.train import Trainer
from inest_reward_node.runtime.intrinsic import IntrinsicConfig
from inest_reward_node.runtime.model import DEFAULT_MODEL

from inest_agent_node.config import SacConfig, TrainConfig

RANDOM_STEPS = 2_000  # random actions, then updates start
# Timing starts once the novelty memory of the first subtask is full: the steady state of a
# long run (a filling memory is cheaper to search).
WARM_UP_STEPS = IntrinsicConfig().capacity + 1_000
# The runs alternate in short rounds and each ratio is taken between neighbouring rounds:
# this machine's speed drifts by tens of percent over minutes, and both sides of a ratio
# should see the same drift.
ROUNDS, ROUND_STEPS = 12, 600


def interleaved_speeds(configs: dict[str, TrainConfig]) -> dict[str, list[float]]:
    """Steps/s of each config in every round of alternating training after the warm-up."""
    with tempfile.TemporaryDirectory() as root:
        trainers = {name: Trainer(config, f"{root}/{name}", progress_bar=False) for name, config in configs.items()}
        return trainer_speeds(trainers)


def trainer_speeds(trainers: dict[str, Trainer]) -> dict[str, list[float]]:
    """Warm every trainer up, then alternate rounds between them; steps/s of each, round by round."""
    for trainer in trainers.values():
        torch.set_num_threads(trainer.config.threads)  # process-wide: each trainer gets its own setting
        trainer.model.learn(WARM_UP_STEPS + 4)
    speeds: dict[str, list[float]] = {name: [] for name in trainers}
    for _ in range(ROUNDS):
        for name, trainer in trainers.items():
            torch.set_num_threads(trainer.config.threads)
            start = time.perf_counter()
            trainer.model.learn(ROUND_STEPS, reset_num_timesteps=False)
            speeds[name].append(ROUND_STEPS / (time.perf_counter() - start))
    return speeds


def paired_ratio(numerator: list[float], denominator: list[float]) -> dict[str, Any]:
    """Median and quartiles over rounds of the speed ratio within each round."""
    quartiles = np.percentile(np.array(numerator) / np.array(denominator), [25, 50, 75])
    return {"ratio": round(float(quartiles[1]), 3), "ratio_quartiles": np.round(quartiles[[0, 2]], 3).tolist()}


def median_speeds(speeds: dict[str, list[float]]) -> dict[str, int]:
    return {name: round(float(np.median(values))) for name, values in speeds.items()}


def main() -> None:
    model = sys.argv[1] if len(sys.argv) > 1 else DEFAULT_MODEL
    threads = int(sys.argv[2]) if len(sys.argv) > 2 else TrainConfig.threads
    torch.set_num_threads(threads)
    common = {
        "threads": threads,
        "num_envs": 4,
        "total_steps": WARM_UP_STEPS + ROUNDS * ROUND_STEPS,
        "eval_every": 10**9,  # no evaluation inside a timed round
        "sac": SacConfig(learning_starts=RANDOM_STEPS),
    }
    speeds = interleaved_speeds(
        {
            "env": TrainConfig(reward="env", intrinsic=IntrinsicConfig(mode="none"), **common),
            "inest": TrainConfig(reward="inest", model=model, **common),
        }
    )
    medians = median_speeds(speeds)
    print(
        json.dumps(
            {
                "benchmark": "train_speed",
                "env_reward_steps_per_s": medians["env"],
                "inest_reward_steps_per_s": medians["inest"],
                **paired_ratio(speeds["inest"], speeds["env"]),
                "target_ratio": 0.8,
                "threads": threads,
                "reward_batch_steps": TrainConfig.reward_batch_steps,
                "settings": "default SAC config, 4 envs; inest: 3 subtasks + embedding bonus",
            }
        )
    )


if __name__ == "__main__":
    main()
