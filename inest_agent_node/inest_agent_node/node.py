"""`inest-agent-node`: SAC trained (or evaluated) over ROS 2 topics, one learner for N simulators.

Parameters: every training setting of config.py (`reward`, `total_steps`, `sac.batch_size`, ...;
`reward` defaults to `topic`, the reward node's reward, or `env` for the simulators' own) plus:
- `mode`: train | evaluate
- `out`: run folder (config.json, checkpoint/, results.json, learning_curve.png, as inest-train)
- `namespaces`: one simulator (and reward stream) per namespace, e.g. ["sim0", "sim1"]
- `resume`: continue the run in `out` from its last checkpoint (refused if it has none)
- `start_over`: train the run in `out` again from step 0, one that stopped before its first checkpoint
- `step_timeout`: seconds of silence before a topic is reported (the node keeps waiting)
- `overlap_updates` (a training setting, on by default here): run each SAC update while the
  simulators take the next step (the action then comes from a policy one update older)
- `episodes`, `policy`, `layouts`: evaluate mode, N episodes of an exported policy (a policy
  folder, or a run folder with one; default: `out`'s) on the named layouts (evaluate.layouts:
  test by default), observed as the policy was trained; written to `out`/evaluation.json
Periodic evaluations during training run on an in-process copy of the simulator.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from inest_common.files import write_atomic
from inest_common.rosutil import declare_dataclass, run_node
from inest_reward_node.learning.runs import check_run_dir
from inest_reward_node.runtime.intrinsic import IntrinsicConfig
from inest_reward_node.runtime.model import ModelError
from rclpy.node import Node

from .config import TrainConfig, setting_defaults
from .envs import with_observation
from .evaluate import evaluate_vec_env, format_table, layouts
from .graph_env import GraphVecEnv
from .policy_export import ExportedPolicy, load_policy
from .rewards import build_reward
from .train import CHECKPOINT_DIR, EVALUATION_FILE, RESULTS_FILE, Trainer, check_resume

MODES = ("train", "evaluate")


@dataclass(frozen=True)
class AgentNodeConfig:
    mode: str = "train"
    out: str = "runs/graph-train"
    namespaces: tuple[str, ...] = ("",)
    resume: bool = False
    start_over: bool = False
    step_timeout: float = 5.0
    episodes: int = 150
    policy: str = ""  # evaluate: an exported policy folder (policy_export.py), or a run folder; empty: `out`
    layouts: str = "test"  # evaluate: the layouts played (evaluate.layouts)

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ValueError(f"unknown mode {self.mode!r}; expected one of {MODES}")
        if not self.namespaces or len(set(self.namespaces)) != len(self.namespaces):
            raise ValueError(f"namespaces must be distinct and at least one, got {list(self.namespaces)}")
        if not self.step_timeout > 0:
            raise ValueError(f"step_timeout must be positive (seconds), got {self.step_timeout}")
        if self.episodes < 1:
            raise ValueError(f"episodes must be at least 1, got {self.episodes}")
        layouts(self.layouts)  # a bad name is refused at start-up


# the rewards a graph brings: the reward node's, scored there with the reward runtime and received
# on each stream's `reward` topic, or the simulators' own in their episode status
GRAPH_REWARDS = ("topic", "env")


def agent_train_defaults() -> TrainConfig:
    """The agent node's training defaults: the reward node's reward, whose intrinsic bonus the
    reward node adds, and one torch thread with updates overlapping the step (the other core
    serves the simulators and the reward node)."""
    return TrainConfig(reward="topic", intrinsic=IntrinsicConfig(mode="none"), threads=1, overlap_updates=True)


class AgentNode(Node):
    def __init__(self) -> None:
        super().__init__("inest_agent_node")
        self.settings = AgentNodeConfig(**declare_dataclass(self, AgentNodeConfig()))
        self.train_config = TrainConfig.from_dict(
            {**declare_dataclass(self, agent_train_defaults()), "num_envs": len(self.settings.namespaces)}
        )
        if self.train_config.reward not in GRAPH_REWARDS:
            raise ValueError(
                f"reward {self.train_config.reward!r} is scored in process by inest-train; over the graph the "
                "reward is the reward node's (topic) or the simulators' own (env)"
            )
        self.policy: ExportedPolicy | None = None  # evaluate mode's, loaded by `check`

    def check(self) -> None:
        """Every refusal before the node joins the graph (run_node's check, which inest-launch's
        runs before it starts any node): evaluate mode's policy, or what Trainer refuses, checked
        without writing anything: the run folder (nothing to resume, a run there already, a resume
        with other settings) and the model of the in-process evaluations' reward."""
        settings, config = self.settings, self.train_config
        if settings.mode == "evaluate":
            self.policy = load_policy(settings.policy or settings.out)
            return
        out = Path(settings.out)
        check_resume(out, settings.resume, settings.start_over)
        continued = settings.resume or settings.start_over
        kept = config.settings_that_matter(settings.start_over)
        check_run_dir(out, config.to_dict(), continued, kept, setting_defaults())
        build_reward(config, 1, evaluation=True)

    def run(self) -> None:
        settings, config = self.settings, self.train_config
        graph = GraphVecEnv(self, list(settings.namespaces), config.reward == "topic", settings.step_timeout)
        try:
            if settings.mode == "evaluate":
                self.evaluate(graph)
                return
            env = with_observation(graph, config.observation, config.stage_subtasks)
            trainer = Trainer(config, settings.out, settings.resume, env=env, start_over=settings.start_over)
            try:
                result = trainer.train()
            except (KeyboardInterrupt, Exception) as error:
                # Ctrl-C or SIGTERM under the step: a KeyboardInterrupt (raised before rclpy's signal
                # thread has shut the context down, so it is not checked), or, once ROS is down, an
                # ExternalShutdownException or an RCLError from a publisher whose context just went
                if not isinstance(error, KeyboardInterrupt) and self.context.ok():
                    raise
                trainer.save_checkpoint()  # keep what was learned
                print(
                    f"inest-agent-node: stopped at step {trainer.model.num_timesteps}; checkpoint saved in "
                    f"{Path(settings.out) / CHECKPOINT_DIR} (resume:=true continues)",
                    flush=True,
                )
                return
            print(format_table({f"{config.reward} ({trainer.model.num_timesteps} steps)": result}), flush=True)
            self.get_logger().info(f"wrote {Path(settings.out) / RESULTS_FILE}")
        finally:
            graph.close()

    def evaluate(self, graph: GraphVecEnv) -> None:
        """An exported policy over the graph, observing what it was trained to observe."""
        settings, policy = self.settings, self.policy
        source = settings.policy or settings.out
        env = with_observation(graph, policy.info["observation"], policy.info["stage_subtasks"])
        on = layouts(settings.layouts)
        result = evaluate_vec_env(env, policy.predict, settings.episodes, on)
        label = f"{Path(source).name} ({policy.info['steps']} steps) over the graph"
        print(format_table({label: result}), flush=True)
        evaluation = {
            "policy": source,
            "label": label,
            "layouts": on.to_dict(),
            "final_evaluation": result.to_dict(),
            "config": self.train_config.to_dict(),
        }
        out = Path(settings.out) / EVALUATION_FILE
        write_atomic(out, lambda path: path.write_text(json.dumps(evaluation, indent=2) + "\n"))
        self.get_logger().info(f"wrote {out}")


def main() -> int:
    return run_node(AgentNode, AgentNode.run, (ValueError, ModelError, FileExistsError), AgentNode.check)
