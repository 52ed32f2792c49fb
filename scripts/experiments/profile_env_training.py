"""Profile in-process SAC training on the environment's reward (4 environments, default SAC
settings, 2 threads): 3,000 steps of warm-up, then 3,000 profiled steps; prints steps/s and the
22 functions with the most own time. Run with a revision's packages first on PYTHONPATH to compare
two revisions' call counts, which machine drift does not change:
  PYTHONPATH=TREE/inest_common:TREE/inest_sim_node:TREE/inest_reward_node:TREE/inest_agent_node \\
    .venv/bin/python scripts/experiments/profile_env_training.py
"""

import cProfile
import pstats
import tempfile
import time

import torch
from inest_agent_node.train import Trainer
from inest_reward_node.runtime.intrinsic import IntrinsicConfig

from inest_agent_node.config import SacConfig, TrainConfig

STEPS = 3_000

torch.set_num_threads(2)
config = TrainConfig(
    reward="env",
    intrinsic=IntrinsicConfig(mode="none"),
    threads=2,
    num_envs=4,
    total_steps=10**6,
    eval_every=10**9,
    sac=SacConfig(learning_starts=2_000),
)
with tempfile.TemporaryDirectory() as root:
    trainer = Trainer(config, f"{root}/run", progress_bar=False)
    trainer.model.learn(STEPS)
    profile = cProfile.Profile()
    start = time.perf_counter()
    profile.enable()
    trainer.model.learn(STEPS, reset_num_timesteps=False)
    profile.disable()
    print(f"steps/s {STEPS / (time.perf_counter() - start):.0f}")
    pstats.Stats(profile).sort_stats("tottime").print_stats(22)
