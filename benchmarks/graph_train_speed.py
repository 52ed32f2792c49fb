"""SAC training speed over the ROS 2 graph next to in-process training, same settings, one run.

In-process: inest-train's Trainer with the INEST reward (3 subtasks, embedding bonus) on 4
environments. Graph: 4 `inest-sim-node` processes (lockstep) and one `inest-reward-node`
(same model, same bonus), the learner in this process on a GraphVecEnv. Rounds alternate
between the two so machine noise hits both alike. Target (issue 5): graph >= 0.9x in-process.
Prints one JSON object. `graph_train_speed.py [MODEL_FOLDER]` (default runs/pretrain-main/model).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import rclpy
import torch
from inest_agent_node.graph_env import GraphVecEnv
from inest_agent_node.train import Trainer
from inest_bringup.launcher import FASTDDS_PROFILE, config_dir
from inest_reward_node.intrinsic import IntrinsicConfig
from train_speed import ROUND_STEPS, ROUNDS, WARM_UP_STEPS, trainer_speeds

from inest_agent_node.config import SacConfig, TrainConfig

SIMS = 4


def main() -> None:
    model = str(Path(sys.argv[1] if len(sys.argv) > 1 else "runs/pretrain-main/model").resolve())
    torch.set_num_threads(TrainConfig.threads)
    domain = 100 + os.getpid() % 50
    env = {
        **os.environ,
        "ROS_DOMAIN_ID": str(domain),
        "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
        "FASTRTPS_DEFAULT_PROFILES_FILE": str(config_dir() / FASTDDS_PROFILE),
    }
    os.environ.update(env)
    namespaces = [f"sim{index}" for index in range(SIMS)]
    bin_dir = Path(sys.executable).parent
    common = {"num_envs": SIMS, "total_steps": WARM_UP_STEPS + ROUNDS * ROUND_STEPS, "eval_every": 10**9}
    sac = SacConfig(learning_starts=WARM_UP_STEPS)
    with tempfile.TemporaryDirectory() as root:
        env["ROS_LOG_DIR"] = root
        processes = [
            subprocess.Popen(
                [bin_dir / "inest-sim-node", "--ros-args", "-r", f"__ns:=/{namespace}", "-p", "cameras:=[ego]"],
                env=env,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
            )
            for namespace in namespaces
        ]
        processes.append(
            subprocess.Popen(
                [
                    bin_dir / "inest-reward-node",
                    "--ros-args",
                    "-p",
                    f"model:={model}",
                    "-p",
                    f"streams:=[{', '.join(namespaces)}]",
                ],
                env=env,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
            )
        )
        rclpy.init(domain_id=domain)
        node = rclpy.create_node("graph_speed_agent")
        graph_env = GraphVecEnv(node, namespaces)
        try:
            trainers = {
                "in_process": Trainer(
                    TrainConfig(reward="inest", model=model, sac=sac, **common), f"{root}/local", progress_bar=False
                ),
                "graph": Trainer(
                    TrainConfig(reward="topic", intrinsic=IntrinsicConfig(mode="none"), sac=sac, **common),
                    f"{root}/graph",
                    progress_bar=False,
                    env=graph_env,
                ),
            }
            speeds = trainer_speeds(trainers)
        finally:
            graph_env.close()
            node.destroy_node()
            rclpy.shutdown()
            for process in processes:
                process.terminate()
                process.wait()
    print(
        json.dumps(
            {
                "benchmark": "graph_train_speed",
                "in_process_steps_per_s": round(speeds["in_process"]),
                "graph_steps_per_s": round(speeds["graph"]),
                "ratio": round(speeds["graph"] / speeds["in_process"], 3),
                "target_ratio": 0.9,
                "settings": f"default SAC config, {SIMS} environments = simulator processes, INEST-3 + embedding bonus",
            }
        )
    )


if __name__ == "__main__":
    main()
