"""`inest-agent-node`: SAC trained (or evaluated) over ROS 2 topics, one learner for N simulators.

Parameters: every training setting of config.py (`reward`, `total_steps`, `sac.batch_size`, ...;
`reward` defaults to `topic`, the reward node's reward, or `env` for the simulators' own) plus:
- `mode`: train | evaluate
- `out`: run folder (config.json, checkpoint/, results.json, learning_curve.png, as inest-train)
- `namespaces`: one simulator (and reward stream) per namespace, e.g. ["sim0", "sim1"]
- `resume`: continue the run in `out` from its last checkpoint
- `step_timeout`: seconds of silence before a topic is reported (the node keeps waiting)
- `overlap_updates`: run each SAC update while the simulators take the next step (default on;
  the action then comes from a policy one update older, see train.OverlappedSAC)
- `episodes`, `policy`: evaluate mode, N episodes of a saved policy (default: `out`'s checkpoint)
Periodic evaluations during training run on an in-process copy of the simulator.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from inest_reward_node.intrinsic import IntrinsicConfig
from inest_reward_node.model import ModelError
from inest_sim_node.rosutil import declare_dataclass, run_node
from rclpy.node import Node
from stable_baselines3 import SAC

from .config import TrainConfig
from .evaluate import EVAL_SEED_OFFSET, EvalResult, format_table
from .graph_env import GraphVecEnv
from .train import CHECKPOINT_DIR, RESULTS_FILE, Trainer

MODES = ("train", "evaluate")


@dataclass(frozen=True)
class AgentNodeConfig:
    mode: str = "train"
    out: str = "runs/graph-train"
    namespaces: tuple[str, ...] = ("",)
    resume: bool = False
    step_timeout: float = 5.0
    episodes: int = 150
    policy: str = ""  # evaluate: a saved SAC model.zip; empty: `out`/checkpoint/model.zip
    overlap_updates: bool = True  # update while the simulators step (train.OverlappedSAC)

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ValueError(f"unknown mode {self.mode!r}; expected one of {MODES}")


def evaluate_over_graph(env: GraphVecEnv, model: SAC, episodes: int, seed: int = 0) -> EvalResult:
    """`episodes` deterministic episodes on the evaluation layouts, run N at a time."""
    scores: list[float] = []
    while len(scores) < episodes:
        count = min(env.num_envs, episodes - len(scores))
        env.seed(EVAL_SEED_OFFSET + seed + len(scores))  # environment i: the next seed + i
        observations = env.reset()
        finished: dict[int, float] = {}
        while len(finished) < count:
            actions, _ = model.predict(observations, deterministic=True)
            observations, _, dones, infos = env.step(actions)
            for index in range(count):
                if dones[index] and index not in finished:
                    finished[index] = infos[index]["score"]
        scores += [finished[index] for index in range(count)]
    return EvalResult.from_scores(scores)


class AgentNode(Node):
    def __init__(self) -> None:
        super().__init__("inest_agent_node")
        self.settings = AgentNodeConfig(**declare_dataclass(self, AgentNodeConfig()))
        # one torch thread: with updates overlapping the step, the other core serves simulators and reward node
        defaults = TrainConfig(reward="topic", intrinsic=IntrinsicConfig(mode="none"), threads=1)
        self.train_config = TrainConfig.from_dict(
            {**declare_dataclass(self, defaults), "num_envs": len(self.settings.namespaces)}
        )

    def run(self) -> None:
        settings, config = self.settings, self.train_config
        env = GraphVecEnv(self, list(settings.namespaces), config.reward == "topic", settings.step_timeout)
        try:
            if settings.mode == "evaluate":
                policy = settings.policy or str(Path(settings.out) / CHECKPOINT_DIR / "model.zip")
                model = SAC.load(policy, env=env)
                result = evaluate_over_graph(env, model, settings.episodes, config.seed)
                print(format_table({f"{Path(policy).name} over the graph": result}), flush=True)
                return
            trainer = Trainer(config, settings.out, settings.resume, env=env, overlap_updates=settings.overlap_updates)
            result = trainer.train()
            print(format_table({f"{config.reward} ({trainer.model.num_timesteps} steps)": result}), flush=True)
            self.get_logger().info(f"wrote {Path(settings.out) / RESULTS_FILE}")
        finally:
            env.close()


def main() -> int:
    return run_node(AgentNode, AgentNode.run, (ValueError, ModelError, FileExistsError))
