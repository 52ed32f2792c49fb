"""The policy's stage observation: what the robot senses, the reward's task stage as a one-hot,
and where the current stage's block lies relative to the robot.

Why: a staged reward (subtask bonus, the tracker's current goal) is not a function of the bare
state vector, so the same state pays differently in two episodes and SAC cannot fit it. The
stage makes the reward Markov; the block's offset in the robot frame tells the policy where
the stage's block is without having to learn the rotation from world coordinates.

"robot" (the default) keeps only what a robot could sense (`ROBOT_FIELDS`: its pose and gripper,
the blocks' poses, their distances and their gaps to the goal), so the task's stage reaches the
policy from the reward alone, as it would on a robot; "stage" keeps the whole simulator state,
the episode score `ordered_progress` and the in-goal flags with it (the earlier default, which
lets a policy ignore a reward that claims the wrong stage); "state" is the bare 21-entry state.
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from .env import STATE_FIELDS
from .scoring import NUM_BLOCKS
from .world import BLOCK_COLOURS

# robot: sensed state + stage one-hot + stage block offsets; stage: the same on the whole state; state: bare
STATE_OBSERVATIONS = ("robot", "stage", "state")
# what the simulator knows and a robot does not: which blocks count as placed, in order
SIMULATOR_ONLY_FIELDS = (*(f"in_goal_{colour}" for colour in BLOCK_COLOURS), "ordered_progress")
ROBOT_FIELDS = tuple(name for name in STATE_FIELDS if name not in SIMULATOR_ONLY_FIELDS)
_ROBOT_COLUMNS = [STATE_FIELDS.index(name) for name in ROBOT_FIELDS]
OFFSET_FIELDS = ("block_forward", "block_lateral", "block_distance")
_X, _Y, _COS, _SIN = (STATE_FIELDS.index(name) for name in ("robot_x", "robot_y", "robot_cos", "robot_sin"))
_BLOCK_X = STATE_FIELDS.index(f"{BLOCK_COLOURS[0]}_x")


def stage_fields(num_subtasks: int) -> tuple[str, ...]:
    """Names of the entries appended to the state vector; stage_<num_subtasks> means all done."""
    return (*(f"stage_{k}" for k in range(num_subtasks + 1)), *OFFSET_FIELDS)


def observation_fields(observation: str, num_subtasks: int) -> tuple[str, ...]:
    """Every entry of an observation of this kind (STATE_OBSERVATIONS), by name."""
    if observation == "state":
        return STATE_FIELDS
    return (*(ROBOT_FIELDS if observation == "robot" else STATE_FIELDS), *stage_fields(num_subtasks))


def claimed_blocks(stages: np.ndarray | int, num_subtasks: int) -> np.ndarray:
    """Blocks placed once `stages` of `num_subtasks` subtasks are done: 3 subtasks are one per block,
    6 are reach/grasp then push per block, 1 is the whole task."""
    return np.asarray(stages, dtype=int) * NUM_BLOCKS // num_subtasks


def stage_block(stages: np.ndarray, num_subtasks: int) -> np.ndarray:
    """Block worked on in each stage (the last block once all are done)."""
    return np.minimum(claimed_blocks(stages, num_subtasks), NUM_BLOCKS - 1)


def stage_observation(
    states: np.ndarray, stages: np.ndarray, num_subtasks: int, sensed_only: bool = False
) -> np.ndarray:
    """(N, 21) states and (N,) stages in 0..num_subtasks -> (N, 21 + num_subtasks + 1 + 3) float32;
    `sensed_only`: the robot's ROBOT_FIELDS in place of the whole state (17 entries, not 21)."""
    states = np.asarray(states, dtype=np.float32).reshape(-1, len(STATE_FIELDS))
    stages = np.asarray(stages, dtype=int).reshape(-1)
    if np.any((stages < 0) | (stages > num_subtasks)):
        raise ValueError(f"stages {stages.tolist()} outside 0..{num_subtasks}")
    rows = np.arange(len(states))
    one_hot = np.zeros((len(states), num_subtasks + 1), dtype=np.float32)
    one_hot[rows, stages] = 1.0
    block = stage_block(stages, num_subtasks)
    offset_x = states[rows, _BLOCK_X + 2 * block] - states[:, _X]
    offset_y = states[rows, _BLOCK_X + 2 * block + 1] - states[:, _Y]
    cos, sin = states[:, _COS], states[:, _SIN]
    forward = -sin * offset_x + cos * offset_y  # heading 0 faces +y, counter-clockwise positive
    lateral = -cos * offset_x - sin * offset_y  # positive: to the robot's left
    offsets = np.stack([forward, lateral, np.hypot(offset_x, offset_y)], axis=1)
    sensed = states[:, _ROBOT_COLUMNS] if sensed_only else states
    return np.concatenate([sensed, one_hot, offsets.astype(np.float32)], axis=1)


def stage_observation_space(state_space: spaces.Box, num_subtasks: int, sensed_only: bool = False) -> spaces.Box:
    reach = float(np.hypot(*(state_space.high[[_X, _Y]] - state_space.low[[_X, _Y]])))
    columns = _ROBOT_COLUMNS if sensed_only else slice(None)
    low = np.concatenate([state_space.low[columns], np.zeros(num_subtasks + 1), [-reach, -reach, 0.0]])
    high = np.concatenate([state_space.high[columns], np.ones(num_subtasks + 1), [reach, reach, reach]])
    return spaces.Box(low.astype(np.float32), high.astype(np.float32), dtype=np.float32)
