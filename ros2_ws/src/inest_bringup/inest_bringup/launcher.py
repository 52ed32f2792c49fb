"""`inest-launch`: start the INEST graph (simulators, reward node, agent) without the ros2 CLI.

For pip set-ups, which have no `ros2 launch`; ROS installs can use launch/inest.launch.py.
All nodes read one params file (config/inest.params.yaml by default). Discovery stays on this
machine (ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST) unless `--discovery subnet`, and uses the
fast-discovery Fast DDS profile shipped next to the params file. The run folder gets each
node's output in logs/, ROS's own logs in logs/ros/, the agent's run in agent/ and, at the end,
reward_trace.png; `--record FILE` adds the recorder (inest-record) to the graph. While the agent
trains, simulators and reward node run `--nice` steps nicer than it (TRAINING_NICENESS) and on
`--env-cpus` (every CPU but the first, so the agent's update has a CPU no simulator runs on).
Before any node starts, each kind is built once with its parameters and model and exits
(`refused_configuration`; the agent also checks its run folder, or in evaluate mode loads its
policy): a bad configuration, like a usage mistake, is one line and exit 2, nothing started or
written. A node that exits is restarted (supervisor.py: `--respawn` times in a row, with
back-off; the agent with resume:=true from its checkpoint, or start_over:=true, said on the
terminal, if it had none); a node that keeps dying or refuses its configuration stops the
graph. Ctrl-C or SIGTERM (or the agent finishing) stops every child, the agent first (it saves a
checkpoint); the launcher then exits 130 (143 for SIGTERM).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from inest_agent_node.evaluate import EvalResult, format_table
from inest_agent_node.train import EVALUATION_FILE, RESULTS_FILE, checkpoint_steps, continuation, has_checkpoint
from inest_common.files import no_space_message, out_of_space, write_atomic
from inest_common.rosutil import CHECK_ONLY_ENV
from inest_common.settings import OneLineParser

from .recording import RecordingError, check_target
from .supervisor import (
    AUTO_CPUS,
    TRAINING_NICENESS,
    RespawnPolicy,
    Supervisor,
    environment_prefix,
    parse_niceness,
    training_cpus,
)

CONFIG_DIR_NAME = "config"
PARAMS_FILE = "inest.params.yaml"
FASTDDS_PROFILE = "fastdds_localhost.xml"
NODES = ("sim", "reward", "agent")
STOP_GRACE_S = 10.0
AGENT_STOP_GRACE_S = 120.0  # the agent writes its checkpoint (model, replay buffer) before it exits
CHECK_POLL_S = 0.05  # how often refused_configuration looks whether a check has ended


def config_dir() -> Path:
    """The installed share/inest_bringup/config, or the source tree's (pip editable install)."""
    try:
        from ament_index_python.packages import get_package_share_directory

        return Path(get_package_share_directory("inest_bringup")) / CONFIG_DIR_NAME
    except (ImportError, LookupError, OSError):
        return Path(__file__).resolve().parents[1] / CONFIG_DIR_NAME


def executable(name: str) -> str:
    """A console script next to this interpreter (the venv's bin/), else on PATH."""
    beside = Path(sys.executable).parent / name
    found = str(beside) if beside.exists() else shutil.which(name)
    if found is None:
        raise FileNotFoundError(f"{name} is not installed (run scripts/setup_env.sh)")
    return found


def graph_environment(domain_id: int | None, ros_log_dir: Path | str, local_only: bool = True) -> dict[str, str]:
    """This process's environment for the nodes of one graph: its domain (None: inherited),
    discovery on this machine only, the fast-discovery profile, ROS's logs in `ros_log_dir`.
    Also what tests and benchmarks use to run their own private graphs."""
    env = dict(os.environ)
    if local_only:
        env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env.setdefault("FASTRTPS_DEFAULT_PROFILES_FILE", str(config_dir() / FASTDDS_PROFILE))
    env["ROS_LOG_DIR"] = str(ros_log_dir)
    if domain_id is not None:
        env["ROS_DOMAIN_ID"] = str(domain_id)
    return env


def simulator_namespaces(count: int) -> list[str]:
    return [f"sim{index}" for index in range(count)]


def node_commands(args: argparse.Namespace, run_dir: Path) -> list[tuple[str, list[str]]]:
    """(log name, argv) of every node to start, in start order."""
    namespaces = simulator_namespaces(args.sims)
    listed = "[" + ", ".join(namespaces) + "]"
    extra: dict[str, list[str]] = {node: [] for node in NODES}
    for setting in args.param:
        node, _, assignment = setting.partition(":")
        if node not in NODES or ":=" not in assignment:
            raise ValueError(f"--param {setting!r}: expected NODE:NAME:=VALUE with NODE one of {NODES}")
        extra[node] += ["-p", assignment]
    params = ["--ros-args", "--params-file", str(args.params)]
    prefix = [] if args.no_agent else environment_prefix(args.nice, args.environment_cpus)
    commands = []
    for index, namespace in enumerate(namespaces):
        clock = [] if index == 0 else ["-p", "publish_clock:=false"]
        if args.realtime:
            clock += ["-p", "mode:=realtime"]
        simulator = [executable("inest-sim-node"), *params, "-r", f"__ns:=/{namespace}", *clock, *extra["sim"]]
        commands.append((namespace, [*prefix, *simulator]))
    model = ["-p", f"model:={args.model}"] if args.model else []
    reward = ["-p", f"streams:={listed}", *model]
    commands.append(("reward", [*prefix, executable("inest-reward-node"), *params, *reward, *extra["reward"]]))
    if not args.no_agent:
        agent = ["-p", f"namespaces:={listed}", "-p", f"out:={run_dir / 'agent'}", *model]
        if args.steps is not None:
            agent += ["-p", f"total_steps:={args.steps}"]
        if args.resume:
            agent += ["-p", "resume:=true"]
        commands.append(("agent", [executable("inest-agent-node"), *params, *agent, *extra["agent"]]))
    if args.record:  # first, so it is subscribed before the first step; a module of this package, always here
        record = [sys.executable, "-m", "inest_bringup.recorder", str(args.record), "--namespaces", *namespaces]
        commands.insert(0, ("record", record))
    return commands


def refused_configuration(commands: list[tuple[str, list[str]]], env: dict[str, str]) -> str | None:
    """Build each kind of node once (one simulator stands for all), in parallel and without joining
    the graph's work (CHECK_ONLY_ENV): every parameter checked, the model loaded, the agent's run
    folder or policy checked before any node starts, so a bad configuration stops nothing
    half-started. The first refusal's line, or None; the other checks are then stopped, so a
    refusal comes as soon as one node has found it. The checks' output and ROS's logs go to a
    scratch folder: a refused launch writes nothing."""
    kinds = {name.rstrip("0123456789"): (name, argv) for name, argv in commands if name != "record"}
    with tempfile.TemporaryDirectory(prefix="inest-launch-check-") as scratch:
        check_env = env | {CHECK_ONLY_ENV: "1", "ROS_LOG_DIR": scratch}
        checks = {}
        for name, argv in kinds.values():
            with open(Path(scratch) / f"{name}.err", "w") as stderr:  # a file: no pipe for the child to fill
                checks[name] = subprocess.Popen(argv, env=check_env, stdout=subprocess.DEVNULL, stderr=stderr)
        while True:
            running = [process for process in checks.values() if process.poll() is None]  # before the next line
            refusal = next((name for name, process in checks.items() if process.poll()), None)
            if refusal or not running:
                break
            time.sleep(CHECK_POLL_S)
        for process in checks.values():
            if process.poll() is None:
                process.kill()
            process.wait()
        if refusal is None:
            return None
        lines = (Path(scratch) / f"{refusal}.err").read_text(errors="replace").strip().splitlines()
        last = lines[-1] if lines else f"exit status {checks[refusal].returncode}"
    return f"{refusal} refused its configuration: {last}"


def print_results(agent_dir: Path) -> None:
    """The table of what the agent wrote: its training run's final evaluation, or a saved policy's."""
    if (path := agent_dir / RESULTS_FILE).exists():
        results = json.loads(path.read_text())
        name = f"{results['config']['reward']} ({results['steps']} steps)"
    elif (path := agent_dir / EVALUATION_FILE).exists():
        results = json.loads(path.read_text())
        name = results["label"]
    else:
        return
    print(format_table({name: EvalResult(**results["final_evaluation"])}))


def stop(children: dict[str, subprocess.Popen]) -> None:
    """SIGINT to each child (agent first, so the learner lets go before its peers vanish)."""
    for name in sorted(children, key=lambda name: name != "agent"):
        process = children[name]
        if process.poll() is None:
            process.send_signal(signal.SIGINT)
            grace = AGENT_STOP_GRACE_S if name == "agent" else STOP_GRACE_S
            try:
                process.wait(grace)
            except subprocess.TimeoutExpired:
                print(f"inest-launch: {name} ignored SIGINT for {grace:.0f} s, killing it", file=sys.stderr)
                process.kill()
                process.wait()


def without_parameters(argv: list[str], assignments: tuple[str, ...]) -> list[str]:
    """`argv` without its `-p NAME:=VALUE` pairs for these assignments."""
    kept: list[str] = []
    for item in argv:
        if item in assignments and kept and kept[-1] == "-p":
            kept.pop()
        else:
            kept.append(item)
    return kept


def resuming_agent(run_dir: Path) -> Callable[[str, list[str]], list[str]]:
    """Restart commands: the agent continues its run from the last checkpoint; one that died before
    its first checkpoint starts its run over, and the launcher says so."""

    def command(name: str, argv: list[str]) -> list[str]:
        agent_dir = run_dir / "agent"
        how = continuation(agent_dir) if name == "agent" else None
        if how is None:
            return argv
        if how == "start_over":
            print(f"inest-launch: the agent stopped before its first checkpoint; its run in {agent_dir} starts over")
        return [*without_parameters(argv, ("resume:=true", "start_over:=true")), "-p", f"{how}:=true"]

    return command


MAX_DOMAIN_ID = 232  # the largest ROS_DOMAIN_ID whose DDS ports fit below 65535 (ROS 2's domain ID docs)


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = OneLineParser(
        prog="inest-launch", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--out", default="runs/graph", help="run folder (logs, agent run, reward trace)")
    parser.add_argument("--params", type=Path, default=config_dir() / PARAMS_FILE, help="ROS params file")
    parser.add_argument("--sims", type=int, default=1, help="simulator processes (namespaces sim0, sim1, ...)")
    parser.add_argument("--model", help="reward model folder (overrides the params file)")
    parser.add_argument("--steps", type=int, help="agent training steps (overrides the params file)")
    parser.add_argument("--resume", action="store_true", help="continue the agent run in OUT/agent")
    parser.add_argument("--no-agent", action="store_true", help="simulators and reward node only")
    parser.add_argument("--realtime", action="store_true", help="simulators step at 8 Hz (implies watching)")
    parser.add_argument("--domain-id", type=int, help="ROS_DOMAIN_ID for every node (default: inherited)")
    parser.add_argument("--discovery", choices=("localhost", "subnet"), default="localhost")
    parser.add_argument("--param", action="append", default=[], metavar="NODE:NAME:=VALUE", help="sim|reward|agent")
    parser.add_argument("--interval", type=float, default=2.0, help="seconds between progress lines")
    parser.add_argument(
        "--episode-lines",
        action="store_true",
        help="a line per finished episode: its score and the steps at which the learned subtask went up",
    )
    parser.add_argument("--record", type=Path, metavar="FILE", help="record the reward topics to this MCAP file")
    parser.add_argument("--respawn", type=int, default=3, help="restarts in a row of a node that exits")
    parser.add_argument("--respawn-delay", type=float, default=1.0, help="seconds before a restart (doubles)")
    parser.add_argument(
        "--nice",
        default=str(TRAINING_NICENESS),
        help="while the agent trains, simulators and reward node run this much nicer (0: same priority)",
    )
    parser.add_argument(
        "--env-cpus",
        default=AUTO_CPUS,
        metavar="CPUS",
        help="while the agent trains, simulators and reward node run on these CPUs (taskset list such as 1 or "
        "1-3; auto: all but the first, leaving that one to the agent's update; all: no confinement)",
    )
    args = parser.parse_args(argv)
    if args.sims < 1:
        parser.error("--sims must be at least 1")
    if args.domain_id is not None and not 0 <= args.domain_id <= MAX_DOMAIN_ID:
        parser.error(f"--domain-id must be in 0..{MAX_DOMAIN_ID} (ROS 2's DDS port range), got {args.domain_id}")
    if args.respawn < 0 or args.respawn_delay < 0:
        parser.error("--respawn and --respawn-delay must be >= 0")
    try:
        args.nice = parse_niceness(args.nice)
    except ValueError as error:
        parser.error(f"--nice {error}")
    try:
        args.environment_cpus = training_cpus(args.env_cpus)  # parsed once, None: no confinement
    except ValueError as error:
        parser.error(f"--env-cpus: {error}")
    if not args.params.is_file():
        parser.error(f"no params file at {args.params}")
    if args.record:
        try:
            check_target(args.record, overwrite=False)
        except RecordingError as error:
            parser.error(str(error))
    return args


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    run_dir = Path(args.out)
    if run_dir.exists() and not run_dir.is_dir():
        print(f"inest-launch: --out {run_dir} is a file, not a folder", file=sys.stderr)
        return 2
    try:
        commands = node_commands(args, run_dir)
    except (ValueError, FileNotFoundError) as error:
        print(f"inest-launch: {error}", file=sys.stderr)
        return 2
    env = graph_environment(args.domain_id, run_dir / "logs" / "ros", args.discovery == "localhost")
    if refusal := refused_configuration(commands, env):
        print(f"inest-launch: {refusal}; nothing was started", file=sys.stderr)
        return 2
    (run_dir / "logs").mkdir(parents=True, exist_ok=True)
    if args.resume and has_checkpoint(agent_dir := run_dir / "agent"):
        steps = checkpoint_steps(agent_dir)
        print(f"inest-launch: the agent resumes {agent_dir} from its checkpoint at step {steps}", flush=True)
    os.environ.update(env)
    import rclpy  # after the environment above: the monitor joins the same graph
    from rclpy.signals import SignalHandlerOptions

    from .monitor import GraphMonitor, watch

    policy = RespawnPolicy(max_respawns=args.respawn, delay=args.respawn_delay)
    supervisor = Supervisor(commands, run_dir / "logs", env, policy, resuming_agent(run_dir))
    stopped_by: list[int] = []  # the signal that asked the launcher to stop
    for number in (signal.SIGINT, signal.SIGTERM):
        signal.signal(number, lambda number, frame: stopped_by.append(number))
    supervisor.start_all()
    # not this process's arguments: rcl would read `--param NODE:NAME:=VALUE` as a deprecated remap rule
    rclpy.init(args=[sys.argv[0]], signal_handler_options=SignalHandlerOptions.NO)  # the handlers above stop it
    monitor = GraphMonitor(simulator_namespaces(args.sims), args.episode_lines)
    status = 0
    try:
        watch(monitor, args.interval, until=lambda: bool(stopped_by) or supervisor.check())
        if stopped_by:
            print("\ninest-launch: stopping", flush=True)
            status = 128 + stopped_by[0]
        elif supervisor.outcome is not None and supervisor.outcome.status:
            print(f"inest-launch: {supervisor.outcome.message}", file=sys.stderr)
            status = supervisor.outcome.status
        else:
            print_results(run_dir / "agent")
    finally:
        stop(supervisor.processes)
        trace = plot_trace(monitor, run_dir / "reward_trace.png")
        monitor.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
    print(f"inest-launch: logs in {run_dir / 'logs'}{trace}")
    return status


def plot_trace(monitor, path: Path) -> str:
    """Write the reward trace; a full disk (the graph may have stopped for it) is said, not raised."""
    try:
        write_atomic(path, lambda partial: monitor.plot(partial))
    except OSError as error:
        if not out_of_space(error):
            raise
        return f"; no reward trace: {no_space_message(error)}"
    return f", reward trace {path}"


if __name__ == "__main__":
    sys.exit(main())
