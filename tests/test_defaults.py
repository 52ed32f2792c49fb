"""One source of defaults: the shipped YAML files restate the dataclasses' defaults, and only the
overrides listed here (each with its reason) differ; every key they set is a real setting."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import yaml
from inest_agent_node.node import AgentNodeConfig, agent_train_defaults
from inest_reward_node.node import RewardNodeConfig
from inest_reward_node.runtime.config import RewardConfig
from inest_reward_node.runtime.intrinsic import IntrinsicConfig
from inest_sim_node.node import SimNodeConfig

from inest_agent_node.config import TrainConfig

ROOT = Path(__file__).resolve().parent.parent
TRAIN_YAML = ROOT / "inest_agent_node" / "config" / "train.yaml"
PARAMS_YAML = ROOT / "ros2_ws" / "src" / "inest_bringup" / "config" / "inest.params.yaml"

# setting -> why the shipped file differs from the dataclass default
TRAIN_OVERRIDES = {"model": "a reward model folder is required for the inest reward; the default has none"}
PARAMS_OVERRIDES = {
    "inest_reward_node": {},
    "inest_agent_node": {"model": "the reward node's model, so in-process evaluations track the stage as it does"},
    "inest_sim_node": {},
}


def defaults_of(cls: type) -> dict[str, Any]:
    """A dataclass's field defaults, nested dataclasses as dicts (without running __post_init__,
    which may require settings such as a model folder)."""
    values = {}
    for field in dataclasses.fields(cls):
        factory = field.default_factory
        default = field.default if factory is dataclasses.MISSING else factory()
        values[field.name] = defaults_of(type(default)) if dataclasses.is_dataclass(default) else default
    return values


def as_plain(value: Any) -> Any:
    if dataclasses.is_dataclass(value):
        return {field.name: as_plain(getattr(value, field.name)) for field in dataclasses.fields(value)}
    return list(value) if isinstance(value, tuple) else value


def differences(shipped: dict[str, Any], defaults: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """{dotted key: (shipped, default)} for every key `shipped` sets to something else; unknown keys
    map to (shipped, "<unknown setting>")."""
    found = {}
    for key, value in shipped.items():
        name = f"{prefix}{key}"
        if key not in defaults:
            found[name] = (value, "<unknown setting>")
        elif isinstance(value, dict) and isinstance(defaults[key], dict):
            found.update(differences(value, defaults[key], f"{name}."))
        elif as_plain(value) != as_plain(defaults[key]):
            found[name] = (value, as_plain(defaults[key]))
    return found


def test_train_yaml_restates_the_training_defaults():
    shipped = yaml.safe_load(TRAIN_YAML.read_text())
    found = differences(shipped, defaults_of(TrainConfig))
    assert set(found) == set(TRAIN_OVERRIDES), found


def test_the_node_parameters_file_restates_each_node_s_defaults():
    shipped = {
        name.removeprefix("/**/"): section["ros__parameters"]
        for name, section in yaml.safe_load(PARAMS_YAML.read_text()).items()
    }
    reward_defaults = {
        **defaults_of(RewardNodeConfig),
        "intrinsic": defaults_of(IntrinsicConfig),
        "reward": {**defaults_of(RewardConfig), "intrinsic_cap": float("inf")},  # declared as a double
    }
    node_defaults = {
        "inest_sim_node": defaults_of(SimNodeConfig),
        "inest_reward_node": reward_defaults,
        "inest_agent_node": {**defaults_of(AgentNodeConfig), **as_plain(agent_train_defaults())},
    }
    assert set(shipped) == set(node_defaults)
    for node, defaults in node_defaults.items():
        found = differences(shipped[node], defaults)
        assert set(found) == set(PARAMS_OVERRIDES[node]), (node, found)
