"""Does a 1M-step INEST run fit in 90 minutes on this machine? The settings of the 1M-step row
of scripts/long_horizon.sh (INEST-3, embedding bonus, the 96 px scene-camera stage heads), in
process on 4 environments with one torch/JAX thread, with and without overlapped updates
(the update on a second thread while the environments step), in alternating rounds after the
warm-up; then each part alone: one vector step of the environments with the learned reward
(random actions), one update (`gradient_steps` gradient steps), one action. Prints one JSON
object with the steps/s, the parts in milliseconds per vector step and the training minutes a
1M-step run would take at the faster speed (periodic evaluations not included).
`million_step_speed.py [MODEL_FOLDER]` (default results/long-horizon/reward-model-scene96).
"""

from __future__ import annotations

import dataclasses
import json
import sys
import tempfile
import time

import numpy as np
import torch
from inest_agent_node.train import Trainer, parse_args
from train_speed import ROUND_STEPS, ROUNDS, WARM_UP_STEPS, median_speeds, paired_ratio, trainer_speeds

MILLION = 1_000_000
PART_REPEATS = 300


def part_ms(call, repeats: int = PART_REPEATS) -> float:
    start = time.perf_counter()
    for _ in range(repeats):
        call()
    return round((time.perf_counter() - start) / repeats * 1000, 2)


def main() -> None:
    model = sys.argv[1] if len(sys.argv) > 1 else "results/long-horizon/reward-model-scene96"
    reward = ["--reward", "inest", "--model", model, "--intrinsic", "embedding", "--stage-evidence", "pixels"]
    flags = [*reward, "--threads", "1", "--eval-every", str(10**9), "--total-steps", str(10**9)]
    with tempfile.TemporaryDirectory() as root:
        config, _ = parse_args(["--config", "inest_agent_node/config/train.yaml", "--out", root, *flags])
        trainers = {
            name: Trainer(dataclasses.replace(config, overlap_updates=overlap), f"{root}/{name}", progress_bar=False)
            for name, overlap in (("plain", False), ("overlapped", True))
        }
        speeds = trainer_speeds(trainers)
        plain = trainers["plain"]
        torch.set_num_threads(config.threads)
        env, sac = plain.env, config.sac
        actions = np.random.default_rng(0).uniform(-1, 1, (env.num_envs, *env.action_space.shape))
        observations = env.reset()
        parts = {
            "environments_with_reward": part_ms(lambda: env.step(actions.astype(np.float32))),
            "update": part_ms(lambda: plain.model.train(gradient_steps=sac.gradient_steps, batch_size=sac.batch_size)),
            "action": part_ms(lambda: plain.model.predict(observations, deterministic=False)),
        }
    medians = median_speeds(speeds)
    fastest = max(medians.values())
    print(
        json.dumps(
            {
                "benchmark": "million_step_speed",
                "steps_per_s": medians,
                "overlapped_to_plain": paired_ratio(speeds["overlapped"], speeds["plain"]),
                "ms_per_vector_step": parts,
                "num_envs": config.num_envs,
                "gradient_steps_per_vector_step": sac.gradient_steps,
                "million_steps_training_minutes": round(MILLION / fastest / 60, 1),
                "target_minutes": 90,
                "settings": f"{' '.join(reward)}, threads 1, rounds of {ROUND_STEPS} steps x {ROUNDS} "
                f"after {WARM_UP_STEPS} warm-up steps, no evaluation",
            }
        )
    )


if __name__ == "__main__":
    main()
