"""SAC training speed with the environment's reward and with the INEST reward, same settings.

Prints one JSON object. Target (issue 4): INEST >= 0.8x the env-reward speed (the encoder
must not be the bottleneck). Needs a reward model: `train_speed.py [MODEL_FOLDER]`
(default runs/pretrain-main/model, which `scripts/run_main.sh` creates).
"""

from __future__ import annotations

import json
import sys
import tempfile
import time

import torch
from inest_agent_node.train import Trainer
from inest_reward_node.intrinsic import IntrinsicConfig

from inest_agent_node.config import SacConfig, TrainConfig

WARM_UP_STEPS = 2_000  # random actions, then updates start
TIMED_STEPS = 6_000


def steps_per_second(config: TrainConfig) -> float:
    with tempfile.TemporaryDirectory() as run_dir:
        trainer = Trainer(config, run_dir, progress_bar=False)
        trainer.model.learn(WARM_UP_STEPS + 4)
        start = time.perf_counter()
        trainer.model.learn(TIMED_STEPS, reset_num_timesteps=False)
        return TIMED_STEPS / (time.perf_counter() - start)


def main() -> None:
    model = sys.argv[1] if len(sys.argv) > 1 else "runs/pretrain-main/model"
    torch.set_num_threads(2)
    common = {
        "num_envs": 4,
        "total_steps": WARM_UP_STEPS + TIMED_STEPS,
        "sac": SacConfig(learning_starts=WARM_UP_STEPS),
    }
    env_speed = steps_per_second(TrainConfig(reward="env", intrinsic=IntrinsicConfig(mode="none"), **common))
    inest_speed = steps_per_second(TrainConfig(reward="inest", model=model, **common))
    print(
        json.dumps(
            {
                "benchmark": "train_speed",
                "env_reward_steps_per_s": round(env_speed),
                "inest_reward_steps_per_s": round(inest_speed),
                "ratio": round(inest_speed / env_speed, 3),
                "target_ratio": 0.8,
                "settings": "default SAC config, 4 envs; inest: 3 subtasks + embedding bonus",
            }
        )
    )


if __name__ == "__main__":
    main()
