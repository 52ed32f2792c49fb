"""SAC training speed over the ROS 2 graph next to in-process training, same SAC settings, one run.

In-process: inest-train's Trainer with the INEST reward (3 subtasks, embedding bonus) on 4
environments, with 1 and with 2 torch threads, and with 1 thread and its updates overlapping
the step on a second thread (`overlap_updates`); the ratio is taken to the fastest. Graph: 4
`inest-sim-node` processes (lockstep; publishing the scene camera too when the model's stage
head reads it, as the default model's does) and one `inest-reward-node` (same model, same bonus),
the learner in this process on a GraphVecEnv, its updates overlapping the simulators' step
(the agent node's default), simulators and reward node TRAINING_NICENESS steps nicer than it and
on every CPU but the first (inest-launch's defaults while the agent trains). Rounds alternate
between the runs so machine noise hits all alike.
Target: graph >= 0.9x in-process. Prints one JSON object; a graph that gives no step with its
reward within FIRST_STEP_TIMEOUT_S ends the run with one line and exit 1.
`graph_train_speed.py [MODEL_FOLDER] [--no-overlap] [--graph-threads=N] [--nice=N] [--env-cpus=CPUS]`
(default model: runtime.model.DEFAULT_MODEL; --no-overlap: updates after each step, as in process;
--nice=0: every node at the agent's priority; --env-cpus=all: nodes on any CPU, as inest-launch's
`--env-cpus`; the nodes' output goes to runs/benchmarks/graph_train_speed/).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import rclpy
import torch
from inest_agent_node.graph_env import GraphVecEnv
from inest_agent_node.train import Trainer
from inest_bringup.launcher import graph_environment
from inest_bringup.supervisor import AUTO_CPUS, TRAINING_NICENESS, environment_prefix, format_cpus, training_cpus
from inest_reward_node.runtime.intrinsic import IntrinsicConfig
from inest_reward_node.runtime.model import DEFAULT_MODEL
from reward_node_harness import fail, stage_camera
from train_speed import RANDOM_STEPS, ROUND_STEPS, ROUNDS, WARM_UP_STEPS, median_speeds, paired_ratio, trainer_speeds

from inest_agent_node.config import SacConfig, TrainConfig

SIMS = 4
FIRST_STEP_TIMEOUT_S = 120  # a graph that gives no step by then never will: the run fails, saying so
BENCHMARK = "graph_train_speed"
LOGS = "runs/benchmarks/graph_train_speed"  # the nodes' output
OVERLAP = "--no-overlap" not in sys.argv  # the agent node's default: updates overlap the step
# torch threads of the graph's learner: with updates overlapping the step, one thread leaves the
# other core to the simulators and the reward node (--graph-threads=2 to match in-process)
GRAPH_THREADS = int(next((a.split("=")[1] for a in sys.argv if a.startswith("--graph-threads=")), "1"))
NICENESS = int(next((a.split("=")[1] for a in sys.argv if a.startswith("--nice=")), str(TRAINING_NICENESS)))
ENV_CPUS = training_cpus(next((a.split("=")[1] for a in sys.argv if a.startswith("--env-cpus=")), AUTO_CPUS))


def first_step(graph_env: GraphVecEnv) -> None:
    """One step of every simulator with its reward, or one line and exit 1 (the graph would wait forever)."""

    def give_up(signal_number: int, frame: object) -> None:
        fail(BENCHMARK, f"no step with its reward from the graph within {FIRST_STEP_TIMEOUT_S} s; see {LOGS}/")

    previous = signal.signal(signal.SIGALRM, give_up)
    signal.alarm(FIRST_STEP_TIMEOUT_S)
    try:
        graph_env.reset()
        graph_env.step(np.zeros((graph_env.num_envs, *graph_env.action_space.shape), np.float32))
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


def main() -> None:
    arguments = [argument for argument in sys.argv[1:] if not argument.startswith("--")]
    model = str(Path(arguments[0] if arguments else DEFAULT_MODEL).resolve())
    torch.set_num_threads(TrainConfig.threads)
    domain = 100 + os.getpid() % 50
    namespaces = [f"sim{index}" for index in range(SIMS)]
    bin_dir = Path(sys.executable).parent
    common = {"num_envs": SIMS, "total_steps": WARM_UP_STEPS + ROUNDS * ROUND_STEPS, "eval_every": 10**9}
    sac = SacConfig(learning_starts=RANDOM_STEPS)
    Path(LOGS).mkdir(parents=True, exist_ok=True)
    prefix = environment_prefix(NICENESS, ENV_CPUS)
    # the simulators publish the cameras the reward node reads: ego, and the stage head's scene camera
    cameras = ["ego", *filter(None, [stage_camera(BENCHMARK, model)])]
    with tempfile.TemporaryDirectory() as root:
        env = graph_environment(domain, root)
        os.environ.update(env)  # this process's own participant joins the same private graph
        processes = [
            subprocess.Popen(
                [
                    *prefix,
                    str(bin_dir / "inest-sim-node"),
                    "--ros-args",
                    "-r",
                    f"__ns:=/{namespace}",
                    "-p",
                    f"cameras:=[{', '.join(cameras)}]",
                ],
                env=env,
                stdout=open(f"{LOGS}/{namespace}.log", "w"),  # noqa: SIM115
                stderr=subprocess.STDOUT,
            )
            for namespace in namespaces
        ]
        processes.append(
            subprocess.Popen(
                [
                    *prefix,
                    str(bin_dir / "inest-reward-node"),
                    "--ros-args",
                    "-p",
                    f"model:={model}",
                    "-p",
                    f"streams:=[{', '.join(namespaces)}]",
                ],
                env=env,
                stdout=open(f"{LOGS}/reward.log", "w"),  # noqa: SIM115
                stderr=subprocess.STDOUT,
            )
        )
        rclpy.init(domain_id=domain)
        node = rclpy.create_node("graph_speed_agent")
        graph_env = GraphVecEnv(node, namespaces)
        try:
            trainers = {
                f"in_process_{threads}_threads": Trainer(
                    TrainConfig(reward="inest", model=model, sac=sac, threads=threads, **common),
                    f"{root}/local{threads}",
                    progress_bar=False,
                )
                for threads in (1, 2)
            }
            trainers["in_process_1_thread_overlapped"] = Trainer(
                TrainConfig(reward="inest", model=model, sac=sac, threads=1, overlap_updates=True, **common),
                f"{root}/local-overlapped",
                progress_bar=False,
            )
            trainers["graph"] = Trainer(
                TrainConfig(
                    reward="topic",
                    model=model,  # the stage observation's in-process evaluations track the stage with it
                    intrinsic=IntrinsicConfig(mode="none"),
                    sac=sac,
                    threads=GRAPH_THREADS,
                    overlap_updates=OVERLAP,
                    **common,
                ),
                f"{root}/graph",
                progress_bar=False,
                env=graph_env,
            )
            first_step(graph_env)
            speeds = trainer_speeds(trainers)
        finally:
            graph_env.close()
            node.destroy_node()
            rclpy.shutdown()
            for process in processes:
                process.terminate()
            for process in processes:  # a node that misses its SIGTERM (seen once, in rclpy's wait) is killed
                try:
                    process.wait(timeout=10)
                except subprocess.TimeoutExpired:
                    process.kill()
                    process.wait()
    medians = median_speeds(speeds)
    fastest_in_process = max((name for name in speeds if name.startswith("in_process")), key=medians.__getitem__)
    ratio = paired_ratio(speeds["graph"], speeds[fastest_in_process])
    print(
        json.dumps(
            {
                "benchmark": BENCHMARK,
                "model": model,
                "cameras": cameras,
                "steps_per_s": medians,
                "ratio_to_faster_in_process": ratio["ratio"],  # the fastest of the in-process runs
                "ratio_quartiles": ratio["ratio_quartiles"],
                "target_ratio": 0.9,
                "overlap_updates": OVERLAP,
                "graph_learner_threads": GRAPH_THREADS,
                "environment_niceness": NICENESS,
                "environment_cpus": format_cpus(ENV_CPUS) if ENV_CPUS else "all",
                "settings": f"default SAC config, {SIMS} environments = simulator processes, INEST-3 + embedding bonus",
            }
        )
    )


if __name__ == "__main__":
    main()
