"""The learner's own state in a checkpoint as arrays and plain JSON, never pickle.

stable-baselines3's `save`/`load` keep every attribute that is not a torch tensor in model.zip's
`data` file, pickled where JSON cannot hold it (SBX's JAX weights and optimiser states among
them), and `load` unpickles each of those entries: resuming a run folder someone else wrote would
run its code. Here a checkpoint holds instead:

- learner.json: the format, the learner's name, its counters (steps, updates, episodes) and the
  updates an overlapped learner still owes (learners.OverlappedUpdatesMixin), as JSON;
- learner.safetensors (the PyTorch learners): the policy's tensors, each optimiser's per-parameter
  state and the entropy coefficient, with the optimisers' settings in learner.json;
- learner.msgpack (the SBX learners): the JAX train states (actor, critics, entropy coefficient)
  and the random key, in flax's msgpack serialisation, which restores arrays into a template of
  the same structure and calls nothing the file names.

Everything else a learner has (its spaces, schedules, network shapes) comes from the run's
config, which built the fresh learner the state is loaded into. A stable-baselines3 model.zip is
never loaded: `refuse_model_zip` names it in one line.
"""

from __future__ import annotations

import json
import operator
import zipfile
from pathlib import Path
from typing import Any

import torch
from inest_common.files import RunFileError, read_run_file, read_versioned_json

FORMAT = "inest-learner-state"
VERSION = 1
STATE_FILE = "learner.json"
TORCH_FILE = "learner.safetensors"
JAX_FILE = "learner.msgpack"
COUNTERS = ("num_timesteps", "_n_updates", "_episode_num")
_JAX_STATES = {  # name in the file -> where it lives on an SBX learner
    "actor_state": "policy.actor_state",
    "qf_state": "policy.qf_state",
    "ent_coef_state": "ent_coef_state",
    "key": "key",
}
_OPTIMISER = "optimiser"  # the JSON entry of an optimiser's settings (its param_groups)


def is_jax(model: Any) -> bool:
    return hasattr(model.policy, "actor_state")


def save_learner_state(model: Any, learner: str, folder: Path) -> list[str]:
    """Write `model`'s state into `folder`; returns the names of the files written."""
    document: dict[str, Any] = {"format": FORMAT, "format_version": VERSION, "learner": learner}
    document["counters"] = {name: int(getattr(model, name)) for name in COUNTERS}
    document["pending_updates"] = [list(update) for update in model.__dict__.get("pending_updates", [])]
    if is_jax(model):
        from flax import serialization

        states = {name: operator.attrgetter(path)(model) for name, path in _JAX_STATES.items()}
        (folder / JAX_FILE).write_bytes(serialization.to_bytes(states))
        arrays_file = JAX_FILE
    else:
        from safetensors.torch import save

        tensors, document["optimisers"] = torch_state(model)
        (folder / TORCH_FILE).write_bytes(save(tensors))  # Python's write: a full disk is an OSError
        arrays_file = TORCH_FILE
    (folder / STATE_FILE).write_text(json.dumps(document, indent=1) + "\n")
    return [arrays_file, STATE_FILE]


def load_learner_state(model: Any, learner: str, folder: Path) -> None:
    """Load the state in `folder` into `model`, a fresh learner built from the run's config.
    RunFileError names the file when it is missing, damaged or another learner's."""
    refuse_model_zip(folder / "model.zip")
    document = read_versioned_json(folder / STATE_FILE, FORMAT, VERSION, "learner state", RunFileError)
    if document.get("learner") != learner:
        raise RunFileError(f"{folder / STATE_FILE} is the state of a {document.get('learner')} learner, not {learner}")
    if is_jax(model):
        import jax
        from flax import serialization
        from msgpack.exceptions import UnpackException

        template = {name: operator.attrgetter(path)(model) for name, path in _JAX_STATES.items()}

        def restore(path: Path) -> Any:
            return serialization.from_bytes(template, path.read_bytes())

        states = read_run_file(folder / JAX_FILE, restore, (UnpackException,))
        states = jax.tree_util.tree_map(jax.numpy.asarray, states)  # msgpack gives numpy arrays back
        shapes = zip(jax.tree_util.tree_leaves_with_path(template), jax.tree_util.tree_leaves(states), strict=True)
        for (where, expected), found in shapes:
            if jax.numpy.shape(expected) != jax.numpy.shape(found):
                raise RunFileError(
                    f"{folder / JAX_FILE} holds {jax.tree_util.keystr(where)} of shape {jax.numpy.shape(found)}, "
                    f"this run's learner {jax.numpy.shape(expected)}: saved with other settings"
                )
        for name, path in _JAX_STATES.items():
            owner, _, attribute = path.rpartition(".")
            setattr(operator.attrgetter(owner)(model) if owner else model, attribute, states[name])
    else:
        from safetensors import SafetensorError
        from safetensors.torch import load_file

        tensors = read_run_file(folder / TORCH_FILE, load_file, (SafetensorError,))
        read_run_file(folder / TORCH_FILE, lambda path: load_torch_state(model, tensors, document["optimisers"]))
    for name, value in document["counters"].items():
        setattr(model, name, int(value))
    if "pending_updates" in vars(model):
        model.pending_updates = [tuple(update) for update in document["pending_updates"]]


def torch_state(model: Any) -> tuple[dict[str, torch.Tensor], dict[str, Any]]:
    """A PyTorch learner's tensors by flat name (module parameters and buffers, each optimiser's
    per-parameter state, the saved variables) and its optimisers' settings (JSON)."""
    tensors: dict[str, torch.Tensor] = {}
    optimisers: dict[str, Any] = {}
    modules, variables = model._get_torch_save_params()  # stable-baselines3's list of what to save
    for name in modules:
        state = operator.attrgetter(name)(model).state_dict()
        if isinstance(operator.attrgetter(name)(model), torch.optim.Optimizer):
            optimisers[name] = state["param_groups"]
            for index, slots in state["state"].items():
                tensors.update({f"{name}/state/{index}/{slot}": value for slot, value in slots.items()})
        else:
            tensors.update({f"{name}/{key}": value for key, value in state.items()})
    for name in variables:
        tensors[f"variable/{name}"] = operator.attrgetter(name)(model).detach()
    return {name: tensor.detach().cpu().contiguous() for name, tensor in tensors.items()}, optimisers


def load_torch_state(model: Any, tensors: dict[str, torch.Tensor], optimisers: dict[str, Any]) -> None:
    modules, variables = model._get_torch_save_params()
    for name in modules:
        target = operator.attrgetter(name)(model)
        prefix = f"{name}/"
        mine = {key[len(prefix) :]: value for key, value in tensors.items() if key.startswith(prefix)}
        if isinstance(target, torch.optim.Optimizer):
            state: dict[int, dict[str, torch.Tensor]] = {}
            for key, value in mine.items():
                _, index, slot = key.split("/")
                state.setdefault(int(index), {})[slot] = value
            target.load_state_dict({"state": state, "param_groups": optimisers[name]})
        else:
            target.load_state_dict(mine, strict=True)
    for name in variables:
        operator.attrgetter(name)(model).data.copy_(tensors[f"variable/{name}"])


def refuse_model_zip(path: Path) -> None:
    """A stable-baselines3 model.zip (an older INEST checkpoint's, or anyone's) is refused: loading
    it would unpickle its `data` entries. The message says which entries are pickled."""
    if not path.exists():
        return
    try:
        with zipfile.ZipFile(path) as archive:
            data = json.loads(archive.read("data"))
        pickled = sorted(key for key, value in data.items() if isinstance(value, dict) and ":serialized:" in value)
    except (OSError, KeyError, ValueError, zipfile.BadZipFile):
        pickled = []
    what = f"pickled entries ({', '.join(pickled)})" if pickled else "a model no INEST checkpoint holds"
    raise RunFileError(
        f"{path} is a stable-baselines3 model.zip with {what}; INEST never loads one, since loading runs "
        f"code the file names: resume from a checkpoint INEST wrote ({STATE_FILE}), or train anew"
    )
