"""The INEST graph for ROS installs: `ros2 launch inest_bringup inest.launch.py sims:=2 model:=...`.

The same nodes and params file as `inest-launch` (the pip set-up's launcher): simulators in
namespaces sim0, sim1, ..., one reward node scoring all of them, one agent learning from all.
`agent:=false` starts simulators and reward node only (e.g. with `mode:=realtime` to watch).
Simulators and reward node respawn as under `inest-launch` (RESPAWN: supervisor.RespawnPolicy's
retries and first delay; ROS launch keeps the delay constant where inest-launch doubles it); the
agent does not (a restarted agent needs resume:=true: start it again with that). While the agent
trains, simulators and reward node run `nice:=N` (10) steps nicer and on `env_cpus:=CPUS` (auto: every
CPU but the first), as under `inest-launch`.
"""

from pathlib import Path

from ament_index_python.packages import get_package_share_directory
from inest_bringup.supervisor import (
    AUTO_CPUS,
    TRAINING_NICENESS,
    RespawnPolicy,
    environment_prefix,
    parse_niceness,
    training_cpus,
)
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction, SetEnvironmentVariable
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

SHARE = Path(get_package_share_directory("inest_bringup"))
POLICY = RespawnPolicy()
RESPAWN = {"respawn": True, "respawn_delay": POLICY.delay, "respawn_max_retries": POLICY.max_respawns}


def graph(context):
    def value(name: str) -> str:
        return LaunchConfiguration(name).perform(context)

    sims = int(value("sims"))
    namespaces = [f"sim{index}" for index in range(sims)]
    params = value("params_file")
    training = value("agent").lower() == "true"
    prefix = {}
    if training:
        nice, env_cpus = value("nice"), value("env_cpus")
        try:
            niceness = parse_niceness(nice)
        except ValueError as error:
            raise ValueError(f"nice:={nice}: {error}") from None
        try:
            cpus = training_cpus(env_cpus)
        except ValueError as error:
            raise ValueError(f"env_cpus:={env_cpus}: {error}") from None
        command = environment_prefix(niceness, cpus)
        prefix = {"prefix": " ".join(command)} if command else {}
    nodes = [
        Node(
            package="inest_sim_node",
            executable="inest-sim-node",
            namespace=namespace,
            parameters=[params, {"publish_clock": index == 0, "mode": value("mode")}],
            output="screen",
            **RESPAWN,
            **prefix,
        )
        for index, namespace in enumerate(namespaces)
    ]
    reward = {"streams": namespaces}
    if value("model"):
        reward["model"] = value("model")
    nodes.append(
        Node(
            package="inest_reward_node",
            executable="inest-reward-node",
            parameters=[params, reward],
            output="screen",
            **RESPAWN,
            **prefix,
        )
    )
    if training:
        agent = {"namespaces": namespaces, "out": value("out")}
        nodes.append(
            Node(package="inest_agent_node", executable="inest-agent-node", parameters=[params, agent], output="screen")
        )
    return nodes


def generate_launch_description() -> LaunchDescription:
    return LaunchDescription(
        [
            DeclareLaunchArgument("params_file", default_value=str(SHARE / "config" / "inest.params.yaml")),
            DeclareLaunchArgument("sims", default_value="1", description="simulator processes"),
            DeclareLaunchArgument(
                "model", default_value="", description="reward model folder (else the params file's)"
            ),
            DeclareLaunchArgument("out", default_value="runs/graph/agent", description="agent run folder"),
            DeclareLaunchArgument("mode", default_value="lockstep", description="simulators: lockstep | realtime"),
            DeclareLaunchArgument("agent", default_value="true", description="start the agent"),
            DeclareLaunchArgument(
                "nice",
                default_value=str(TRAINING_NICENESS),
                description="while the agent trains, simulators and reward node run this much nicer (0: off)",
            ),
            DeclareLaunchArgument(
                "env_cpus",
                default_value=AUTO_CPUS,
                description="while the agent trains, simulators and reward node run on these CPUs "
                "(taskset list; auto: all but the first, leaving that one to the agent's update; all: anywhere)",
            ),
            SetEnvironmentVariable("FASTRTPS_DEFAULT_PROFILES_FILE", str(SHARE / "config" / "fastdds_localhost.xml")),
            OpaqueFunction(function=graph),
        ]
    )
