"""A trained policy as a small, self-describing folder: the actor's weights (`actor.safetensors`,
a few hundred kB against the 9 MB of the learner's checkpoint state with its critics and
optimiser: the mean's layers and, in policies exported since it was added, the log standard
deviation's layer, so its rollouts can sample actions as training did) and what it observes
(`policy.json`: the observation, the stage scheme, each entry's name, the run's full training config).

Why: a committed policy can be re-evaluated on new layouts, with a new metric or after a bug
fix in evaluation without retraining, and without the learner's library; the SAC family's
deterministic action is tanh of the actor's mean, an MLP that numpy runs.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from inest_common.files import RunFileError, read_run_file, read_versioned_json, write_atomic
from inest_sim_node.observation import observation_fields
from safetensors.numpy import load_file, save_file

from .config import TrainConfig

POLICY_DIR = "policy"
ACTOR_FILE = "actor.safetensors"
POLICY_FILE = "policy.json"
FORMAT = "inest-policy"
VERSION = 1
EXPORTABLE = ("sac", "sbx_sac", "sbx_droq")  # plain MLP actors; CrossQ's batch renormalisation is not exported


LOG_STD_RANGE = (-20.0, 2.0)  # where both libraries clip the actor's log standard deviation
Layer = tuple[np.ndarray, np.ndarray]  # weight (out, in), bias


def actor_layers(model: Any, learner: str) -> tuple[list[Layer], Layer]:
    """Each hidden layer and then the mean layer of a SAC-family actor, and its log std layer."""
    if learner == "sac":  # stable-baselines3: actor.latent_pi (Linear, ReLU, ...), actor.mu, actor.log_std
        linear = [module for module in model.actor.latent_pi if hasattr(module, "weight")]
        linear += [model.actor.mu, model.actor.log_std]
        layers = [(layer.weight.detach().cpu().numpy(), layer.bias.detach().cpu().numpy()) for layer in linear]
    elif learner in ("sbx_sac", "sbx_droq"):  # SBX: Dense_0..Dense_{n-1} hidden, Dense_n mean, Dense_{n+1} log std
        params = model.policy.actor_state.params["params"]
        dense = sorted((name for name in params if name.startswith("Dense_")), key=lambda name: int(name[6:]))
        layers = [(np.asarray(params[name]["kernel"]).T, np.asarray(params[name]["bias"])) for name in dense]
    else:
        raise ValueError(f"exporting a {learner} policy is not supported; exportable learners: {EXPORTABLE}")
    return layers[:-1], layers[-1]


@dataclass
class ExportedPolicy:
    """The actor: relu hidden layers, then tanh of the mean (actions in [-1, 1]), or of a sample
    around it with the log std layer's spread (policies exported before it was kept have none)."""

    layers: list[Layer]
    info: dict[str, Any]  # policy.json
    log_std: Layer | None = None

    @property
    def config(self) -> TrainConfig:
        """The training config of the run the policy comes from."""
        return TrainConfig.from_dict(self.info["train_config"])

    def _features(self, observations: np.ndarray) -> np.ndarray:
        x = np.asarray(observations, np.float32)
        if x.ndim != 2 or x.shape[1] != self.layers[0][0].shape[1]:
            raise ValueError(f"the policy observes {self.layers[0][0].shape[1]} values, got shape {x.shape}")
        for weight, bias in self.layers[:-1]:
            x = np.maximum(x @ weight.T + bias, 0.0)
        return x

    def predict(self, observations: np.ndarray) -> np.ndarray:
        """The deterministic action: tanh of the mean."""
        weight, bias = self.layers[-1]
        return np.tanh(self._features(observations) @ weight.T + bias)

    def sample(self, observations: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """An action drawn as training drew it: tanh of mean + exp(log std) x standard normal."""
        if self.log_std is None:
            raise ValueError("this policy was exported without its log std layer: it has mean actions only")
        features = self._features(observations)
        (weight, bias), (std_weight, std_bias) = self.layers[-1], self.log_std
        mean = features @ weight.T + bias
        log_std = np.clip(features @ std_weight.T + std_bias, *LOG_STD_RANGE)
        return np.tanh(mean + np.exp(log_std) * rng.standard_normal(mean.shape))


def exported(model: Any, config: TrainConfig) -> ExportedPolicy:
    """The learner's policy now, as it is exported: what training's evaluations play, so that a
    re-evaluation of the exported policy repeats them exactly (JAX's and numpy's float sums
    differ in the last bits, which the physics turns into other episodes)."""
    info = {
        "format": FORMAT,
        "format_version": VERSION,
        "steps": int(model.num_timesteps),
        "observation": config.observation,
        "stage_subtasks": config.stage_subtasks,
        "observation_fields": list(observation_fields(config.observation, config.stage_subtasks)),
        "train_config": config.to_dict(),
    }
    mean_path, log_std = actor_layers(model, config.learner)
    layers = [(np.array(w, np.float32), np.array(b, np.float32)) for w, b in mean_path]
    return ExportedPolicy(layers, info, (np.array(log_std[0], np.float32), np.array(log_std[1], np.float32)))


def export_policy(model: Any, config: TrainConfig, folder: str | Path) -> Path:
    """Write the policy of a SAC-family learner to `folder` (actor first, then policy.json)."""
    folder = Path(folder)
    policy = exported(model, config)
    tensors = {}
    named = [(f"layer{index}", layer) for index, layer in enumerate(policy.layers)]
    for name, (weight, bias) in [*named, ("log_std", policy.log_std)]:
        tensors[f"{name}.weight"] = np.ascontiguousarray(weight)
        tensors[f"{name}.bias"] = np.ascontiguousarray(bias)
    write_atomic(folder / ACTOR_FILE, lambda path: save_file(tensors, str(path)))
    write_atomic(folder / POLICY_FILE, lambda path: path.write_text(json.dumps(policy.info, indent=2) + "\n"))
    return folder


def load_policy(folder: str | Path) -> ExportedPolicy:
    """A policy folder (export_policy's), or a run folder holding one in `policy/`."""
    folder = Path(folder)
    if not (folder / POLICY_FILE).exists() and (folder / POLICY_DIR / POLICY_FILE).exists():
        folder = folder / POLICY_DIR
    if folder.is_dir() and not (folder / POLICY_FILE).exists():
        raise RunFileError(
            f"{folder} holds no exported policy ({POLICY_DIR}/{POLICY_FILE}): runs trained before inest-train "
            "exported its actor have none"
        )
    info = read_versioned_json(folder / POLICY_FILE, FORMAT, VERSION, "exported policy", RunFileError)
    tensors = read_run_file(folder / ACTOR_FILE, lambda path: load_file(str(path)))
    count = sum(name.startswith("layer") for name in tensors) // 2
    try:
        layers = [(tensors[f"layer{i}.weight"], tensors[f"layer{i}.bias"]) for i in range(count)]
    except KeyError as error:
        raise RunFileError(f"{folder / ACTOR_FILE} lacks {error.args[0]}") from None
    log_std = (tensors["log_std.weight"], tensors["log_std.bias"]) if "log_std.weight" in tensors else None
    return ExportedPolicy(layers, info, log_std)
