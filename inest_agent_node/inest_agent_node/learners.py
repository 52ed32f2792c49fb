"""The off-policy learners the agent can train with, and the project's two SAC behaviours on any of them.

Pure (no rclpy). Every learner here is a stable-baselines3 `OffPolicyAlgorithm`: SBX's JAX
algorithms subclass it too (sbx.common.off_policy_algorithm.OffPolicyAlgorithmJax, checked for
sbx-rl 0.28.0), so `learn()` drives them all through the same two hooks the project overrides:
`_store_transition(replay_buffer, buffer_action, new_obs, reward, dones, infos)` after every
vector step and `train(gradient_steps, batch_size)` after every rollout. Both behaviours are
therefore mixins that go on top of whichever class `LEARNERS` names (`build_learner_class`):

- OverlappedUpdatesMixin overrides `OffPolicyAlgorithm.train(gradient_steps, batch_size)` (it
  defers the update to `run_pending_updates`, which calls the learner's own `train`);
- RewardBatchingMixin overrides `OffPolicyAlgorithm._store_transition(...)` (holds a transition
  until its learned reward is scored);
- BrokenStepsMixin overrides `OffPolicyAlgorithm._store_transition(...)` too (stores nothing for
  a vector step on which an environment's step never happened).

Neither touches `learn()`, `collect_rollouts()` or the policy; what runs around `learn()`
(progress, evaluation, diagnostics, checkpoints) is callbacks.py's stable-baselines3 callbacks.

JAX is imported only when an SBX learner is picked (`learner_class`), so the PyTorch path never
pays its import time nor starts its thread pools; call `configure_jax_threads`
before that.
"""

from __future__ import annotations

import dataclasses
import importlib
import inspect
import os
import sys
import warnings
from collections import deque
from collections.abc import Iterator, Mapping, Sequence
from functools import cache
from typing import Any, ClassVar, Protocol


class DataclassInstance(Protocol):
    """Any dataclass instance (what `dataclasses.asdict` takes)."""

    __dataclass_fields__: ClassVar[dict[str, Any]]


# name -> "module:attribute" of the class, imported on first use (see _LazyLearners);
# sbx_droq is built by _sbx_droq (a subclass of sbx.SAC)
_LEARNER_PATHS: dict[str, str] = {
    "sac": "stable_baselines3:SAC",
    "sbx_sac": "sbx:SAC",
    "crossq": "sb3_contrib:CrossQ",
    "sbx_crossq": "sbx:CrossQ",
    "sbx_droq": f"{__name__}:_sbx_droq",
}
# readable class names, the stem of the names build_learner_class gives its variants
_CLASS_STEMS: dict[str, str] = {
    "sac": "SAC",
    "sbx_sac": "SbxSAC",
    "crossq": "CrossQ",
    "sbx_crossq": "SbxCrossQ",
    "sbx_droq": "SbxDroQ",
}

# SBX's documented DroQ configuration of SAC (its README, "Note about DroQ"): dropout and layer
# normalisation in every critic layer. The paper's 20 gradient steps per environment step (and
# policy_delay 20) are a replay ratio, not part of the network: learner_kwargs keeps the
# project's gradient_steps, which was chosen for CPU speed.
DROQ_POLICY_KWARGS: dict[str, Any] = {"dropout_rate": 0.01, "layer_norm": True}
# CrossQ's critic width in both sb3-contrib 2.9.2 and sbx-rl 0.28.0 when net_arch is not given
# (the paper used 2048; the libraries chose 1024 for speed): the wide critic is what CrossQ's
# authors found to matter, so learner_kwargs keeps it unless told otherwise.
CROSSQ_CRITIC_ARCH: tuple[int, ...] = (1024, 1024)
# SacConfig fields a learner's constructor does not take (CrossQ has no target network, so no tau)
_DROPPED_SETTINGS: dict[str, frozenset[str]] = {
    "crossq": frozenset({"tau"}),
    "sbx_crossq": frozenset({"tau"}),
}


@cache
def _sbx_droq() -> type:
    """SBX SAC in its DroQ configuration (dropout + layer norm in the critic).

    SBX dropped its DroQ class in 0.16.0 (`sbx.DroQ` now raises ImportError) in favour of these
    SAC policy settings; a named subclass keeps "sbx_droq" a class like the others, so models
    saved with it load with it. Explicit policy_kwargs entries win over the DroQ defaults.
    """
    from sbx import SAC

    class SbxDroQ(SAC):
        __doc__ = _sbx_droq.__doc__

        def __init__(self, *args: Any, policy_kwargs: dict[str, Any] | None = None, **kwargs: Any) -> None:
            super().__init__(*args, policy_kwargs={**DROQ_POLICY_KWARGS, **(policy_kwargs or {})}, **kwargs)

    SbxDroQ.__init__.__signature__ = inspect.signature(SAC.__init__)  # the keywords it takes: SAC's
    SbxDroQ.__module__, SbxDroQ.__qualname__ = __name__, "SbxDroQ"
    return SbxDroQ


def _resolve(path: str) -> type:
    if path == f"{__name__}:_sbx_droq":
        return _sbx_droq()
    module, attribute = path.split(":")
    return getattr(importlib.import_module(module), attribute)


class _LazyLearners(Mapping[str, type]):
    """name -> learner class, importing a learner's library only when its class is asked for
    (iterating the names or testing `in` imports nothing)."""

    def __getitem__(self, name: str) -> type:
        return _resolve(_LEARNER_PATHS[name])

    def __contains__(self, name: object) -> bool:
        return name in _LEARNER_PATHS  # Mapping's own would import the class

    def __iter__(self) -> Iterator[str]:
        return iter(_LEARNER_PATHS)

    def __len__(self) -> int:
        return len(_LEARNER_PATHS)

    def __repr__(self) -> str:
        return f"LEARNERS({', '.join(_LEARNER_PATHS)})"


LEARNERS: Mapping[str, type] = _LazyLearners()


def learner_class(name: str) -> type:
    """The plain learner class called `name` (see LEARNERS); imports JAX for the sbx_* ones."""
    if name not in LEARNERS:
        raise ValueError(f"unknown learner {name!r}; expected one of {tuple(LEARNERS)}")
    return LEARNERS[name]


class OverlappedUpdatesMixin:
    """Gradient steps that run while the environments take their next step.

    Overrides stable-baselines3's `OffPolicyAlgorithm.train(gradient_steps, batch_size)`, which
    `learn()` calls after each rollout: stable-baselines3 stores transition t, updates, then picks
    the action for t + 1. Here `train` only records the call; the action for t + 1 is picked
    first (by a policy one update older), sent, and the update runs in `run_pending_updates`
    while the simulators and the reward node work in their own processes; it still samples from
    exactly the transitions up to t. The vector env calls `run_pending_updates` once its actions
    are out (GraphVecEnv.while_waiting); call it once more after `learn()` returns (the last
    update had no next step to overlap with). `pending_updates` is saved with the learner's state
    (learner_state.py), so a checkpoint taken between the two keeps the deferred update.
    """

    pending_updates: list[tuple[int, int]]

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.__dict__.setdefault("pending_updates", [])

    def train(self, gradient_steps: int, batch_size: int = 64) -> None:
        self.__dict__.setdefault("pending_updates", []).append((gradient_steps, batch_size))

    def run_pending_updates(self) -> None:
        pending = self.__dict__.setdefault("pending_updates", [])
        while pending:
            super().train(*pending.pop(0))  # the learner's own train()


class RewardBatchingMixin:
    """For a RewardVecEnv that scores several vector steps' frames at once.

    A transition waits until its learned reward is known (at most batch_steps - 1 vector steps),
    then goes into the replay buffer exactly as the learner would have stored it; the updates
    meanwhile sample from the transitions already stored. Overrides stable-baselines3's
    `OffPolicyAlgorithm._store_transition` (handing it a TransitionHolder for the replay buffer);
    a checkpoint calls `settle_rewards` first, so no transition is held in it. stable-baselines3
    hands `_store_transition` fresh arrays every step, so holding them is safe. The env must offer
    `take_rewards(at_most)` and `score_waiting()` (envs.RewardVecEnv).
    """

    held_transitions: deque[tuple[Any, ...]]

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.held_transitions = deque()
        if self.env is not None:
            self.env.accept_deferred_rewards()  # this learner never trains on a reward still NaN

    def _store_transition(self, replay_buffer, buffer_action, new_obs, reward, dones, infos) -> None:
        holder = TransitionHolder(self.held_transitions)
        super()._store_transition(holder, buffer_action, new_obs, reward, dones, infos)
        self.store_scored_transitions()

    def store_scored_transitions(self) -> None:
        """Move every held transition whose reward the env has scored into the replay buffer."""
        # at a checkpoint the current step is scored before the learner hands over its transition
        for reward in self.env.take_rewards(len(self.held_transitions)):
            observation, next_observation, action, _, dones, infos = self.held_transitions.popleft()
            self.replay_buffer.add(observation, next_observation, action, reward, dones, infos)

    def settle_rewards(self) -> None:
        """Score the frames still waiting for a full batch and store their transitions (checkpoints)."""
        self.env.score_waiting()
        self.store_scored_transitions()


BROKEN_STEP = "broken_step"  # info flag: this environment's step never happened (GraphVecEnv: its simulator restarted)


class BrokenStepsMixin:
    """For the graph's simulators, which can restart mid-episode (GraphVecEnv): an environment whose
    step never happened has no next observation, only a new episode's first one. The vector step it
    is part of is not stored; a replay buffer row holds every environment's transition, so with N
    simulators the others lose that one transition each, and nothing else is dropped."""

    def _store_transition(self, replay_buffer, buffer_action, new_obs, reward, dones, infos) -> None:
        if any(info.get(BROKEN_STEP) for info in infos):
            self._last_obs = new_obs  # what stable-baselines3 does after storing: act on the new observations
            return
        super()._store_transition(replay_buffer, buffer_action, new_obs, reward, dones, infos)


class TransitionHolder:
    """Stands in for the replay buffer in `_store_transition`: keeps the transition it is given."""

    def __init__(self, held: deque[tuple[Any, ...]]) -> None:
        self.held = held

    def add(self, *transition: Any) -> None:
        self.held.append(transition)


def _variant_name(name: str, overlap_updates: bool, reward_batching: bool, drops_broken_steps: bool = False) -> str:
    prefix = ("Overlapped" if overlap_updates else "") + ("RewardBatching" if reward_batching else "")
    return prefix + ("BrokenStepDropping" if drops_broken_steps else "") + _CLASS_STEMS[name]


def build_learner_class(
    name: str, overlap_updates: bool = False, reward_batching: bool = False, drops_broken_steps: bool = False
) -> type:
    """The learner `name` with the chosen mixins, e.g. ("sbx_sac", overlap_updates=True) -> OverlappedSbxSAC.

    One class per combination (cached), so two trainers of one configuration build the same
    class; with neither mixin it is the plain class of LEARNERS.
    """
    return _build_learner_class(name, bool(overlap_updates), bool(reward_batching), bool(drops_broken_steps))


@cache  # positional, normalised arguments: one cache entry, so one class, per combination
def _build_learner_class(name: str, overlap_updates: bool, reward_batching: bool, drops_broken_steps: bool) -> type:
    base = learner_class(name)
    mixins = (
        (OverlappedUpdatesMixin,) * overlap_updates
        + (RewardBatchingMixin,) * reward_batching
        + (BrokenStepsMixin,) * drops_broken_steps
    )
    if not mixins:
        return base
    class_name = _variant_name(name, overlap_updates, reward_batching, drops_broken_steps)
    doc = f"{base.__name__} ({name}) with " + " and ".join(mixin.__name__ for mixin in mixins) + "."
    return type(class_name, (*mixins, base), {"__module__": __name__, "__qualname__": class_name, "__doc__": doc})


def learner_kwargs(name: str, sac: DataclassInstance, critic_net_arch: Sequence[int] | None = None) -> dict[str, Any]:
    """Constructor keywords (besides policy, env, seed, logging) for learner `name` from the project's SAC settings
    (`sac`: a config.SacConfig, which names the learners from LEARNERS).

    Every SacConfig field passes through under its own name (learning_rate, buffer_size,
    learning_starts, batch_size, tau, gamma, train_freq, gradient_steps, ent_coef) except:
    - net_arch becomes policy_kwargs["net_arch"] (actor and critic alike);
    - crossq, sbx_crossq: tau is dropped (CrossQ has no target network: batch renormalisation
      replaces it), and the critic keeps CrossQ's wide CROSSQ_CRITIC_ARCH unless
      `critic_net_arch` is given (the actor gets net_arch); learning_rate is the project's, not
      CrossQ's default 1e-3, and policy_delay stays CrossQ's default 3;
    - sbx_droq: policy_kwargs also carries DROQ_POLICY_KWARGS (gradient_steps stays the project's).
    `critic_net_arch` sets the critic width of any learner. No library is imported.
    """
    if name not in LEARNERS:
        raise ValueError(f"unknown learner {name!r}; expected one of {tuple(LEARNERS)}")
    settings = dataclasses.asdict(sac)
    actor = list(settings.pop("net_arch"))
    for dropped in _DROPPED_SETTINGS.get(name, ()):
        settings.pop(dropped)
    critic = list(critic_net_arch) if critic_net_arch is not None else None
    if critic is None and name in ("crossq", "sbx_crossq"):
        critic = list(CROSSQ_CRITIC_ARCH)
    net_arch: list[int] | dict[str, list[int]] = actor if critic is None else {"pi": actor, "qf": critic}
    policy_kwargs: dict[str, Any] = {"net_arch": net_arch}
    if name == "sbx_droq":
        policy_kwargs.update(DROQ_POLICY_KWARGS)
    return {**settings, "policy_kwargs": policy_kwargs}


def configure_jax_threads(threads: int) -> None:
    """Keep JAX's CPU compute to `threads` threads; call before JAX's CPU backend starts.

    Measured with jaxlib 0.10.2 on this 2-core machine: the XLA CPU client sizes its compute
    pool (threads named tf_XLAEigen) from the PJRT_NPROC environment variable, else from the
    process's CPU affinity, and reads it once, when the backend starts (the first array or
    jax.devices(), not `import jax` nor `import sbx`). PJRT_NPROC=1 moved all compute onto the
    calling thread and PJRT_NPROC=4 gave 4 pool threads. The often-quoted
    XLA_FLAGS="--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=N" changed
    neither the pool size nor which threads did the work in this jaxlib, so it is not set.
    os.sched_setaffinity would also work but binds the whole process (PyTorch, children) to
    those cores. About 12-15 further, mostly idle runtime threads (compilation, async dispatch)
    exist whatever is set. JAX does not preallocate memory on CPU (XLA_PYTHON_CLIENT_PREALLOCATE
    is a GPU setting), so there is nothing to turn off there.

    Warns (and changes nothing that is already running) if the backend has started.
    """
    if threads < 1:
        raise ValueError(f"threads must be at least 1, got {threads}")
    os.environ["PJRT_NPROC"] = str(threads)
    if "jax" in sys.modules:
        from jax._src import xla_bridge

        if xla_bridge.backends_are_initialized():
            warnings.warn(
                "JAX's CPU backend has already started: its thread count stays as it was "
                f"(configure_jax_threads({threads}) must run before the first JAX computation)",
                RuntimeWarning,
                stacklevel=2,
            )
