"""`inest-evaluate`: re-evaluate committed policies on any layouts without retraining.

Each RUN is a training run folder with its exported policy (`policy/`, written by inest-train at
every checkpoint) or a policy folder itself. The policy plays through the observation path and
reward of its own training config (the learned reward's stage reaches its observation), with the
reward model that config names. One table row per run; each run's evaluation is written to
RUN/evaluations/<layouts>-<episodes>.json (or --out, for one run). `--layouts locked --release
NAME` scores a release's headline rows on the locked test set, once per run, and records each in
the ledger with the commit that scored it (release_ledger).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from collections.abc import Callable
from pathlib import Path

from inest_agent_node.envs import build_env
from inest_agent_node.evaluate import LOCKED, EvalResult, evaluate_vec_env, format_table, layouts
from inest_agent_node.policy_export import POLICY_DIR, ExportedPolicy, load_policy
from inest_common.files import write_atomic
from inest_common.settings import OneLineParser
from inest_reward_node.learning.stage_refit import REFIT_MODEL_DIR
from inest_reward_node.runtime.model import ModelError
from stable_baselines3.common.vec_env import VecEnv

from .release_ledger import (
    LEDGER,
    check_distinct,
    check_unscored,
    default_ledger,
    in_repository,
    read_ledger,
    repository,
    scoring_commit,
)
from .release_ledger import record as record_scoring

EVALUATIONS_DIR = "evaluations"
MAX_ENVS = 10  # episodes played side by side (one encoder pass for all their frames)


def run_home(run: Path) -> Path:
    """The training run folder of RUN, given either it or its policy folder."""
    return run.parent if run.name == POLICY_DIR else run


def policy_and_env(
    run: Path, num_envs: int, wrap_simulators: Callable[[VecEnv], VecEnv] | None = None
) -> tuple[ExportedPolicy, VecEnv]:
    """The run's exported policy and `num_envs` environments of its training config's observation
    path and reward (evaluation's: no intrinsic bonus), with the stage classifier it refitted last."""
    policy = load_policy(run)
    refitted = run_home(run) / REFIT_MODEL_DIR  # the stage classifier the run refitted last (stage_refit)
    config = dataclasses.replace(policy.config, model=str(refitted)) if refitted.exists() else policy.config
    env = build_env(config, num_envs=num_envs, evaluation=True, wrap_simulators=wrap_simulators)
    if env.observation_space.shape != (policy.layers[0][0].shape[1],):
        env.close()
        raise ValueError(
            f"{run}: the policy observes {policy.layers[0][0].shape[1]} values, its config's "
            f"observation path gives {env.observation_space.shape[0]}"
        )
    return policy, env


def reevaluate(run: Path, spec: str, episodes: int, release: bool = False) -> tuple[EvalResult, dict]:
    """The run's exported policy on the layouts `spec` (inest_agent_node.evaluate.layouts, of the run's seed)."""
    policy, env = policy_and_env(run, min(MAX_ENVS, episodes))
    try:
        on = layouts(spec, policy.config.seed, release)
        on.check(episodes)
    except ValueError:
        env.close()
        raise
    try:
        start = time.monotonic()
        result = evaluate_vec_env(env, policy.predict, episodes, on)
    finally:
        env.close()
    record = {
        "run": str(run),
        "policy_steps": policy.info["steps"],
        "layouts": on.to_dict(),
        "evaluation": result.to_dict(),
        "wall_clock_s": round(time.monotonic() - start, 2),
    }
    return result, record


def main(argv: list[str] | None = None) -> int:
    parser = OneLineParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("runs", nargs="+", type=Path, help="run folders (with policy/) or policy folders")
    parser.add_argument(
        "--layouts",
        default="test",
        help="test (default), validation, legacy (the run's earlier ones), FIRST:STOP, or locked with --release",
    )
    parser.add_argument("--episodes", type=int, default=150)
    parser.add_argument("--out", type=Path, help="the evaluation's JSON file (one run only)")
    parser.add_argument("--release", help="with --layouts locked: the release these headline rows are for")
    parser.add_argument(
        "--ledger", type=Path, help=f"the locked set's ledger (default: {LEDGER} of the git repository you are in)"
    )
    args = parser.parse_args(argv)
    if args.episodes < 1:
        parser.error("--episodes must be at least 1")
    if args.out is not None and len(args.runs) > 1:
        parser.error("--out takes one run; several write RUN/evaluations/ each")
    locked = args.layouts == LOCKED
    if locked != bool(args.release):
        parser.error(
            "--layouts locked and --release NAME go together: the locked set is scored once per run, for a release"
        )
    rows = {}
    try:
        layouts(args.layouts, release=locked)  # a bad name fails before any model loads
        if locked:  # every run unscored and the code committed, before any scoring
            ledger_path = args.ledger or default_ledger()
            commit, ledger = scoring_commit(ledger_path), read_ledger(ledger_path)
            top = repository(ledger_path)
            check_distinct([in_repository(run_home(run), top) for run in args.runs])
            for run in args.runs:
                check_unscored(ledger, in_repository(run_home(run), top))
        for run in args.runs:
            result, record = reevaluate(run, args.layouts, args.episodes, locked)
            name = f"{args.layouts.replace(':', '-')}-{args.episodes}.json"
            out = args.out or run_home(run) / EVALUATIONS_DIR / name
            write_atomic(out, lambda path, record=record: path.write_text(json.dumps(record, indent=2) + "\n"))
            if locked:
                scored = {"episodes": args.episodes, "evaluation": record["evaluation"]}
                record_scoring(ledger_path, ledger, in_repository(run_home(run), top), args.release, commit, scored)
            rows[str(run)] = result
            print(f"wrote {out}", file=sys.stderr)
    except (ModelError, ValueError) as error:
        print(f"inest-evaluate: {error}", file=sys.stderr)
        return 2
    print(format_table(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
