"""`inest-record-exploit-suite RUN... --part development|held-out --out DIR`: trained policies'
own rollouts as one part of the exploit suite (inest_reward_node.learning.exploit_suite), on
which `inest-exploit-suite` scores any reward model.

Each RUN is a training run folder with its exported policy; it plays through its own observation
path and reward (as `inest-evaluate` does), `--episodes` episodes on layouts of its own that no
other episode uses, and every step's body poses, true progress and grasp flag are kept. Actions
are sampled as in training where the exported actor kept its log std layer; policies exported
before it was kept play their mean actions (the part's `policies` entries say which).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np
from inest_agent_node.envs import TRUE_PROGRESS
from inest_agent_node.evaluate import evaluate_vec_env, layouts
from inest_common.progress import track
from inest_common.settings import OneLineParser
from inest_reward_node.learning.clips import ClipError
from inest_reward_node.learning.exploit_suite import (
    FIRST_SEEDS,
    PARTS,
    SEEDS_PER_POLICY,
    SuiteEpisode,
    SuitePart,
    save_part,
    suite_file,
)
from inest_reward_node.runtime.model import ModelError
from stable_baselines3.common.vec_env import VecEnv

from inest_agent_node.config import TrainConfig

from .record_clips import RolloutRecorder
from .reevaluate import MAX_ENVS, policy_and_env

POSES = "body_poses"


def describe_policy(config: TrainConfig, steps: int, sampled: bool, mean_score: float) -> dict[str, Any]:
    """What a suite reader needs to know of a policy: the reward it learned from and how well it did here."""
    return {
        "reward": config.reward,
        "model": config.model if config.reward != "env" else None,
        "tracker": config.learned_reward.tracker,
        "stage_evidence": config.learned_reward.stage_evidence,
        "intrinsic": config.intrinsic.mode,
        "observation": config.observation,
        "seed": config.seed,
        "policy_steps": steps,
        "actions": "sampled, as in training" if sampled else "mean (exported without its log std)",
        "mean_score_here": round(mean_score, 4),
    }


def record_policy(run: Path, episodes: int, first_seed: int) -> tuple[list[SuiteEpisode], dict[str, Any]]:
    """`episodes` rollouts of the run's exported policy on the layouts first_seed, first_seed + 1, ..."""
    recorders: list[RolloutRecorder] = []

    def keep(venv: VecEnv) -> VecEnv:
        recorders.append(RolloutRecorder(venv, (POSES, TRUE_PROGRESS, "held")))
        return recorders[-1]

    policy, env = policy_and_env(run, min(MAX_ENVS, episodes), keep)
    sampled = policy.log_std is not None
    rng = np.random.default_rng(first_seed)
    act = (lambda observations: policy.sample(observations, rng)) if sampled else policy.predict
    try:
        result = evaluate_vec_env(env, act, episodes, layouts(f"{first_seed}:{first_seed + episodes}"))
    finally:
        env.close()
    rollouts = [
        SuiteEpisode(str(run), first_seed + index, poses.astype("float32"), progress, held)
        for index, (poses, progress, held) in enumerate(recorders[0].episodes[:episodes])
    ]
    return rollouts, describe_policy(policy.config, policy.info["steps"], sampled, result.mean_score)


def main(argv: list[str] | None = None) -> int:
    parser = OneLineParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("runs", nargs="+", type=Path, help="training run folders with an exported policy")
    parser.add_argument("--part", required=True, choices=PARTS)
    parser.add_argument("--episodes", type=int, default=20, help="rollouts per policy (default %(default)s)")
    parser.add_argument("--out", type=Path, required=True, help="the suite's folder; writes PART.npz there")
    args = parser.parse_args(argv)
    if not 1 <= args.episodes <= SEEDS_PER_POLICY:
        parser.error(f"--episodes must be between 1 and {SEEDS_PER_POLICY}")
    if len(set(args.runs)) != len(args.runs):
        parser.error("a run is named twice")
    episodes: list[SuiteEpisode] = []
    policies: dict[str, dict[str, Any]] = {}
    try:
        args.out.mkdir(parents=True, exist_ok=True)  # before the rollouts, not after
        for index, run in enumerate(track(args.runs, desc="policies", unit="policy")):
            first_seed = FIRST_SEEDS[args.part] + SEEDS_PER_POLICY * index
            rollouts, policies[str(run)] = record_policy(run, args.episodes, first_seed)
            episodes += rollouts
        save_part(suite_file(args.out, args.part), SuitePart(args.part, episodes, policies))
    except (ModelError, ClipError, ValueError, OSError) as error:
        print(f"inest-record-exploit-suite: {error}", file=sys.stderr)
        return 2
    for run, described in policies.items():
        print(f"{run}: mean score {described['mean_score_here']:.3f} over {args.episodes} episodes")
    print(f"wrote {suite_file(args.out, args.part)}: {len(episodes)} episodes of {len(policies)} policies")
    return 0


if __name__ == "__main__":
    sys.exit(main())
