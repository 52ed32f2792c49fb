"""Gradient updates per second of each off-policy learner (learners.LEARNERS), side by side.

Prints one JSON object (and writes it to --out). Every learner updates from its own replay
buffer holding the same 10,000 random transitions of the training observation (the
simulator's state plus the 7 stage entries: 28 dims) and action (3 dims), so only the update
itself is timed: sampling, the gradient steps, the logging, as `learn()` calls it. Each
`train()` call does --gradient-steps updates (default: the training config's), like one
vector step of training. The first calls (JIT compilation for the SBX learners, reported as
warm_up_s) are not timed. CrossQ runs twice: with its wide default critic and with a critic
of --net-arch.

The learners alternate in short rounds and each reports the median and quartiles over rounds:
this machine's speed drifts over minutes (and other work may share its 2 cores; the load
average before and after is in the output), and all learners should see the same drift.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from importlib.metadata import version
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np
import torch
from gymnasium import spaces
from inest_agent_node.learners import (
    CROSSQ_CRITIC_ARCH,
    LEARNERS,
    configure_jax_threads,
    learner_class,
    learner_kwargs,
)
from stable_baselines3.common.vec_env import DummyVecEnv

from inest_agent_node.config import SacConfig
from inest_sim_node import STATE_FIELDS

STAGE_ENTRIES = 7  # the stage observation's one-hot and block offsets on top of the state
OBSERVATION_DIM = len(STATE_FIELDS) + STAGE_ENTRIES  # 28
ACTION_DIM = 3
TRANSITIONS = 10_000
WARM_UP_CALLS = 3
NARROW = "@narrow_critic"  # suffix of the CrossQ entries whose critic is --net-arch wide


class ShapesOnly(gymnasium.Env):
    """The training spaces, for constructing a learner; the benchmark never steps it."""

    observation_space = spaces.Box(-np.inf, np.inf, (OBSERVATION_DIM,), np.float32)
    action_space = spaces.Box(-1.0, 1.0, (ACTION_DIM,), np.float32)

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        return np.zeros(OBSERVATION_DIM, np.float32), {}

    def step(self, action):
        raise NotImplementedError("the benchmark only trains from the replay buffer")


def fill_replay_buffer(model, seed: int = 0) -> None:
    """TRANSITIONS random transitions, the same for every learner."""
    rng = np.random.default_rng(seed)
    buffer = model.replay_buffer
    observations = rng.uniform(-1, 1, (TRANSITIONS + 1, 1, OBSERVATION_DIM)).astype(np.float32)
    buffer.observations[:TRANSITIONS] = observations[:-1]
    buffer.next_observations[:TRANSITIONS] = observations[1:]
    buffer.actions[:TRANSITIONS] = rng.uniform(-1, 1, (TRANSITIONS, 1, ACTION_DIM))
    buffer.rewards[:TRANSITIONS] = rng.uniform(0, 1, (TRANSITIONS, 1))
    buffer.dones[:TRANSITIONS] = rng.uniform(0, 1, (TRANSITIONS, 1)) < 1 / 200
    buffer.pos, buffer.full = TRANSITIONS, False


def build_models(names: list[str], sac: SacConfig) -> dict[str, Any]:
    """One learner per entry, with its replay buffer filled; CrossQ also with a narrow critic."""
    models: dict[str, Any] = {}
    for name in names:
        variants = {name: None}
        if "crossq" in name:
            variants[name + NARROW] = list(sac.net_arch)
        for entry, critic in variants.items():
            env = DummyVecEnv([ShapesOnly])
            kwargs = learner_kwargs(name, sac, critic_net_arch=critic)
            kwargs["buffer_size"] = TRANSITIONS
            model = learner_class(name)("MlpPolicy", env, seed=0, verbose=0, **kwargs)
            model.set_logger(_quiet_logger())
            fill_replay_buffer(model)
            models[entry] = model
    return models


def _quiet_logger():
    from stable_baselines3.common.logger import configure

    return configure(None, [])


def interleaved_speeds(
    models: dict[str, Any], sac: SacConfig, rounds: int, updates: int
) -> tuple[dict[str, list[float]], dict[str, float]]:
    """Updates/s of each model in every round, after an untimed warm-up; and each warm-up's seconds."""
    steps = sac.gradient_steps
    calls = max(1, updates // steps)
    warm_up: dict[str, float] = {}
    for entry, model in models.items():
        start = time.perf_counter()
        for _ in range(WARM_UP_CALLS):
            model.train(gradient_steps=steps, batch_size=sac.batch_size)
        warm_up[entry] = round(time.perf_counter() - start, 2)
    speeds: dict[str, list[float]] = {entry: [] for entry in models}
    for _ in range(rounds):
        for entry, model in models.items():
            start = time.perf_counter()
            for _ in range(calls):
                model.train(gradient_steps=steps, batch_size=sac.batch_size)
            speeds[entry].append(calls * steps / (time.perf_counter() - start))
    return speeds, warm_up


def summary(speeds: dict[str, list[float]]) -> dict[str, dict[str, Any]]:
    result = {}
    for entry, values in speeds.items():
        quartiles = np.percentile(values, [25, 50, 75])
        result[entry] = {
            "updates_per_s": round(float(quartiles[1]), 1),
            "quartiles": np.round(quartiles[[0, 2]], 1).tolist(),
        }
    return result


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--batch-size", type=int, default=256)
    parser.add_argument("--net-arch", type=int, nargs="+", default=[256, 256], help="hidden sizes, e.g. 256 256")
    parser.add_argument("--gradient-steps", type=int, default=SacConfig.gradient_steps, help="updates per train() call")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--updates", type=int, default=100, help="updates per learner and round")
    parser.add_argument("--threads", type=int, default=2, help="torch and JAX compute threads")
    parser.add_argument("--learners", nargs="+", default=list(LEARNERS), choices=list(LEARNERS))
    parser.add_argument("--out", help="also write the JSON line to this file")
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> None:
    args = parse_args(argv)
    configure_jax_threads(args.threads)  # before any SBX learner starts JAX
    torch.set_num_threads(args.threads)
    sac = SacConfig(batch_size=args.batch_size, net_arch=tuple(args.net_arch), gradient_steps=args.gradient_steps)
    load_before = os.getloadavg()
    started = time.perf_counter()
    models = build_models(args.learners, sac)
    speeds, warm_up = interleaved_speeds(models, sac, args.rounds, args.updates)
    results = summary(speeds)
    packages = ["torch", "stable-baselines3", "sb3-contrib", "sbx-rl", "jax", "jaxlib", "flax"]
    report = {
        "benchmark": "learner_speed",
        "learners": results,
        "fastest": max(results, key=lambda entry: results[entry]["updates_per_s"]),
        "warm_up_s": warm_up,
        "batch_size": args.batch_size,
        "net_arch": args.net_arch,
        "crossq_default_critic": list(CROSSQ_CRITIC_ARCH),
        "crossq_narrow_critic": args.net_arch,
        "gradient_steps_per_call": args.gradient_steps,
        "rounds": args.rounds,
        "updates_per_round": max(1, args.updates // args.gradient_steps) * args.gradient_steps,
        "threads": args.threads,
        "observation_dim": OBSERVATION_DIM,
        "action_dim": ACTION_DIM,
        "replay_transitions": TRANSITIONS,
        "load_average_1min_before_after": [round(load_before[0], 2), round(os.getloadavg()[0], 2)],
        "cpu_count": os.cpu_count(),
        "wall_s": round(time.perf_counter() - started, 1),
        "versions": {package: version(package) for package in packages},
    }
    line = json.dumps(report)
    print(line)
    if args.out:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(line + "\n")


if __name__ == "__main__":
    main()
