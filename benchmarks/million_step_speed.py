"""Does a 1M-step INEST run fit in 90 minutes on this machine? The settings of the 1M-step rows
of scripts/long_horizon.sh (INEST-3, embedding bonus, the 96 px scene-camera stage heads), in
process on 4 environments with one torch/JAX thread, with and without overlapped updates
(the update on a second thread while the environments step), at 2 and at 1 gradient steps per
vector step (replay ratios 0.5 and 0.25), in alternating rounds after the warm-up; then each
part alone: one vector step of the environments with the learned reward (random actions), one
update of each size, one action. Prints one JSON object with the steps/s, the parts in
milliseconds per vector step and, per replay ratio, the training minutes a 1M-step run would
take at its faster speed (periodic evaluations not included).
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
GRADIENT_STEPS = (2, 1)  # per vector step of 4 environments: the default, and the 1M-step row's
PART_REPEATS = 300


def part_ms(call, repeats: int = PART_REPEATS) -> float:
    start = time.perf_counter()
    for _ in range(repeats):
        call()
    return round((time.perf_counter() - start) / repeats * 1000, 2)


def fastest(medians: dict[str, int], gradient_steps: int) -> int:
    """Steps/s of the faster of the plain and overlapped runs at this many gradient steps."""
    return max(medians[f"{mode}_gradient_steps_{gradient_steps}"] for mode in ("plain", "overlapped"))


def main() -> None:
    model = sys.argv[1] if len(sys.argv) > 1 else "results/long-horizon/reward-model-scene96"
    reward = ["--reward", "inest", "--model", model, "--intrinsic", "embedding", "--stage-evidence", "pixels"]
    flags = [*reward, "--threads", "1", "--eval-every", str(10**9), "--total-steps", str(10**9)]
    with tempfile.TemporaryDirectory() as root:
        config, _ = parse_args(["--config", "inest_agent_node/config/train.yaml", "--out", root, *flags])
        trainers = {
            f"{mode}_gradient_steps_{steps}": Trainer(
                dataclasses.replace(
                    config, overlap_updates=overlap, sac=dataclasses.replace(config.sac, gradient_steps=steps)
                ),
                f"{root}/{mode}{steps}",
                progress_bar=False,
            )
            for steps in GRADIENT_STEPS
            for mode, overlap in (("plain", False), ("overlapped", True))
        }
        speeds = trainer_speeds(trainers)
        plain = trainers[f"plain_gradient_steps_{GRADIENT_STEPS[0]}"]
        torch.set_num_threads(config.threads)
        env, batch_size = plain.env, config.sac.batch_size
        actions = np.random.default_rng(0).uniform(-1, 1, (env.num_envs, *env.action_space.shape))
        observations = env.reset()
        parts = {
            "environments_with_reward": part_ms(lambda: env.step(actions.astype(np.float32))),
            **{
                f"update_{steps}_gradient_steps": part_ms(
                    lambda steps=steps: plain.model.train(gradient_steps=steps, batch_size=batch_size)
                )
                for steps in GRADIENT_STEPS
            },
            "action": part_ms(lambda: plain.model.predict(observations, deterministic=False)),
        }
    medians = median_speeds(speeds)
    print(
        json.dumps(
            {
                "benchmark": "million_step_speed",
                "steps_per_s": medians,
                "overlapped_to_plain": {
                    f"gradient_steps_{steps}": paired_ratio(
                        speeds[f"overlapped_gradient_steps_{steps}"], speeds[f"plain_gradient_steps_{steps}"]
                    )
                    for steps in GRADIENT_STEPS
                },
                "ms_per_vector_step": parts,
                "num_envs": config.num_envs,
                "million_steps_training_minutes": {
                    f"gradient_steps_{steps}": round(MILLION / fastest(medians, steps) / 60, 1)
                    for steps in GRADIENT_STEPS
                },
                "target_minutes": 90,
                "settings": f"{' '.join(reward)}, threads 1, rounds of {ROUND_STEPS} steps x {ROUNDS} "
                f"after {WARM_UP_STEPS} warm-up steps, no evaluation",
            }
        )
    )


if __name__ == "__main__":
    main()
