"""One source of defaults: the dataclasses. The shipped YAML files set only the overrides listed
here (each with its reason), each a real setting that differs from its default."""

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

from inest_agent_node.config import SacConfig, TrainConfig

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


def keys_set(shipped: dict[str, Any], prefix: str = "") -> set[str]:
    """Every dotted key a YAML document sets."""
    found = set()
    for key, value in shipped.items():
        found |= keys_set(value, f"{prefix}{key}.") if isinstance(value, dict) else {f"{prefix}{key}"}
    return found


def test_train_yaml_sets_only_its_overrides():
    shipped = yaml.safe_load(TRAIN_YAML.read_text())
    found = differences(shipped, defaults_of(TrainConfig))
    assert set(found) == keys_set(shipped) == set(TRAIN_OVERRIDES), found


def test_the_whole_training_config_is_printed_from_the_defaults(capsys):
    from inest_agent_node.train import main

    assert main(["--config", str(TRAIN_YAML), "--print-config"]) == 0
    printed = yaml.safe_load(capsys.readouterr().out)
    assert printed == TrainConfig.from_yaml(TRAIN_YAML).to_dict()
    assert printed["model"] == "runs/pretrain-tcc/model" and printed["sac"]["batch_size"] == SacConfig().batch_size


def test_the_node_parameters_file_sets_only_its_overrides():
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
    assert set(shipped) <= set(node_defaults)
    for node, defaults in node_defaults.items():
        found = differences(shipped.get(node, {}), defaults)
        assert set(found) == keys_set(shipped.get(node, {})) == set(PARAMS_OVERRIDES[node]), (node, found)
