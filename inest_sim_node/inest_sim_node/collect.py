"""Collect a demonstration dataset with the scripted expert (`inest-collect-demos`).

Seeds are tried in order from `--seed`; only episodes the expert completes (score 1)
are kept, ending on the frame where the last block counts. The first 80% of kept
episodes form the train split, the rest the validation split, whatever the number of
worker processes. Re-running with the same arguments resumes an interrupted collection;
different arguments on an existing dataset are refused, so nothing saved is lost.
"""

from __future__ import annotations

import dataclasses
import json
import multiprocessing
import platform
import sys
from dataclasses import asdict, dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import cv2
import gymnasium
import numpy as np
import pymunk
from inest_common.progress import track
from inest_common.settings import OneLineParser

from . import __version__
from .config import EnvConfig
from .dataset import (
    FORMAT,
    FORMAT_VERSION,
    METADATA_FILE,
    DatasetError,
    Episode,
    read_metadata,
    write_episode,
    write_metadata,
)
from .env import STATE_FIELDS, SweepToTopEnv
from .expert import ExpertConfig, ScriptedExpert
from .subtasks import DESCRIPTIONS, SCHEMES, subtask_labels


@dataclass(frozen=True)
class CollectConfig:
    episodes: int = 1000
    valid_fraction: float = 0.2  # thesis: 800 train / 200 validation
    seed: int = 0
    image_size: int = EnvConfig.image_size
    max_steps: int = EnvConfig.max_steps
    workers: int = 2

    def __post_init__(self) -> None:
        for name in ("episodes", "image_size", "max_steps", "workers"):
            if getattr(self, name) <= 0:
                raise ValueError(f"{name} must be positive, got {getattr(self, name)}")
        if not 0.0 <= self.valid_fraction < 1.0:
            raise ValueError(f"valid_fraction must be in [0, 1), got {self.valid_fraction}")

    @property
    def train_episodes(self) -> int:
        return self.episodes - round(self.episodes * self.valid_fraction)


def record_episode(env: SweepToTopEnv, expert: ScriptedExpert, seed: int) -> Episode | None:
    """Play the expert from `seed` with both cameras; None if it does not finish in time."""
    env.reset(seed=seed)
    expert.reset(seed=seed)
    size = env.config.image_size
    ego, allo = [env.render_camera("ego", size)], [env.render_camera("allo", size)]
    states, progress, held = [env.state_vector()], [env.progress], [env.holds_current_block]
    actions, rewards = [], []
    truncated, success = False, False
    while not (truncated or success):
        action = expert.act(env)
        _, reward, _, truncated, info = env.step(action)
        success = info["is_success"]
        ego.append(env.render_camera("ego", size))
        allo.append(env.render_camera("allo", size))
        states.append(env.state_vector())
        progress.append(env.progress)
        held.append(env.holds_current_block)
        actions.append(action)
        rewards.append(reward)
    if not success:
        return None
    labels, ends = {}, {}
    for scheme in SCHEMES:
        labels[scheme], ends[scheme] = subtask_labels(np.array(progress), np.array(held), scheme)
    return Episode(
        seed=seed,
        ego=np.stack(ego),
        allo=np.stack(allo),
        actions=np.asarray(actions, dtype=np.float32),
        states=np.stack(states),
        rewards=np.asarray(rewards, dtype=np.float32),
        progress=np.asarray(progress, dtype=np.int8),
        labels=labels,
        ends=ends,
        text=np.array([DESCRIPTIONS[3][label] for label in labels[3]]),
    )


# --- worker processes -----------------------------------------------------------------
_WORKER: dict[str, Any] = {}


def _init_worker(env_config: EnvConfig, expert_config: ExpertConfig, root: Path) -> None:
    cv2.setNumThreads(1)
    _WORKER.update(env=SweepToTopEnv(config=env_config), expert=ScriptedExpert(expert_config), root=root)


def _collect_seed(seed: int) -> dict[str, Any] | None:
    episode = record_episode(_WORKER["env"], _WORKER["expert"], seed)
    if episode is None:
        return None
    relative = f"episodes/seed_{seed:06d}.npz"
    sha256 = write_episode(_WORKER["root"] / relative, episode)
    return {
        "file": relative,
        "seed": seed,
        "frames": len(episode),
        "sha256": sha256,
        "content_sha256": episode.content_sha256(),
    }


# --- the collection -------------------------------------------------------------------
def _versions() -> dict[str, str]:
    return {
        "inest_sim_node": __version__,
        "python": platform.python_version(),
        "numpy": np.__version__,
        "pymunk": pymunk.version,
        "opencv": cv2.__version__,
        "gymnasium": gymnasium.__version__,
    }


def _config_record(collect: CollectConfig, env: EnvConfig, expert: ExpertConfig) -> dict[str, Any]:
    return {"collect": asdict(collect), "env": env.to_dict(), "expert": asdict(expert)}


def _differences(old: Any, new: Any, prefix: str = "") -> list[str]:
    if isinstance(old, dict) and isinstance(new, dict):
        keys = sorted(set(old) | set(new))
        return [d for k in keys for d in _differences(old.get(k), new.get(k), f"{prefix}{k}.")]
    return [] if old == new else [prefix.rstrip(".")]


def _start_or_resume(root: Path, record: dict[str, Any]) -> dict[str, Any]:
    """Fresh metadata, or the saved one when it was made with the same configuration."""
    if (root / METADATA_FILE).exists():
        saved = read_metadata(root)
        # JSON turns tuples into lists; compare like with like.
        differing = _differences(saved["config"], json_round_trip(record))
        if differing:
            raise DatasetError(
                f"{root} holds a dataset made with other settings (differs in: {', '.join(differing)}); "
                "choose another --out folder, or delete that one yourself"
            )
        return saved
    if root.exists() and any(root.iterdir()):
        raise DatasetError(f"refusing to write into {root}: it is not empty and holds no {METADATA_FILE}")
    return {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "created": datetime.now(UTC).isoformat(timespec="seconds"),
        "config": record,
        "versions": _versions(),
        "state_fields": list(STATE_FIELDS),
        "label_schemes": {str(s): list(DESCRIPTIONS[s]) for s in SCHEMES},
        "kept": [],
        "failed_seeds": [],
        "next_seed": record["collect"]["seed"],
        "complete": False,
    }


def json_round_trip(value: Any) -> Any:
    return json.loads(json.dumps(value))


def _save_progress(root: Path, metadata: dict[str, Any], collect: CollectConfig) -> None:
    kept = metadata["kept"][: collect.episodes]
    metadata["episodes"] = {"train": kept[: collect.train_episodes], "valid": kept[collect.train_episodes :]}
    metadata["complete"] = len(kept) >= collect.episodes
    write_metadata(root, metadata)


def collect_dataset(
    root: str | Path,
    collect: CollectConfig | None = None,
    expert: ExpertConfig | None = None,
    show_progress: bool = True,
) -> dict[str, Any]:
    """Write (or finish) a dataset in `root`; returns its metadata."""
    root = Path(root)
    collect = collect or CollectConfig()
    expert = expert or ExpertConfig()
    env_config = EnvConfig(image_size=collect.image_size, max_steps=collect.max_steps)
    metadata = _start_or_resume(root, _config_record(collect, env_config, expert))
    root.mkdir(parents=True, exist_ok=True)
    needed = collect.episodes - len(metadata["kept"])
    if needed <= 0:
        _save_progress(root, metadata, collect)
        return metadata
    # workers forked from a fresh server process, never from this one: a fork of a process whose
    # other threads (PyTorch's, JAX's, OpenCV's pools) hold a lock left a worker waiting forever
    # on it (seen once in the test suite); Python 3.14 makes forkserver Linux's default for that reason
    context = multiprocessing.get_context("spawn" if sys.platform == "darwin" else "forkserver")
    with (
        context.Pool(collect.workers, _init_worker, (env_config, expert, root)) as pool,
        track(
            total=collect.episodes, initial=len(metadata["kept"]), desc="demonstrations", disable=not show_progress
        ) as bar,
    ):
        while needed > 0:
            # Ask for a few more seeds than needed: the expert fails a few percent of layouts.
            seeds = range(metadata["next_seed"], metadata["next_seed"] + needed + needed // 10 + collect.workers)
            for seed, entry in zip(seeds, pool.imap(_collect_seed, seeds), strict=True):
                metadata["next_seed"] = seed + 1
                if entry is None:
                    metadata["failed_seeds"].append(seed)
                elif needed > 0:
                    metadata["kept"].append(entry)
                    needed -= 1
                    bar.update(1)
                else:  # finished by a surplus worker after the target was reached
                    (root / entry["file"]).unlink(missing_ok=True)
                if len(metadata["kept"]) % 25 == 0:
                    _save_progress(root, metadata, collect)
    _save_progress(root, metadata, collect)
    return metadata


def main(argv: list[str] | None = None) -> int:
    defaults = CollectConfig()
    parser = OneLineParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, required=True, help="dataset folder to create or resume")
    parser.add_argument("--episodes", type=int, default=defaults.episodes)
    parser.add_argument("--valid-fraction", type=float, default=defaults.valid_fraction)
    parser.add_argument("--seed", type=int, default=defaults.seed, help="first layout seed")
    parser.add_argument("--image-size", type=int, default=defaults.image_size)
    parser.add_argument("--max-steps", type=int, default=defaults.max_steps)
    parser.add_argument("--workers", type=int, default=defaults.workers)
    parser.add_argument("--noise", type=float, default=ExpertConfig().action_noise, help="expert action noise std")
    args = parser.parse_args(argv)
    try:
        collect = CollectConfig(
            episodes=args.episodes,
            valid_fraction=args.valid_fraction,
            seed=args.seed,
            image_size=args.image_size,
            max_steps=args.max_steps,
            workers=args.workers,
        )
        expert = dataclasses.replace(ExpertConfig(), action_noise=args.noise)
        metadata = collect_dataset(args.out, collect, expert)
    except (ValueError, DatasetError) as error:
        print(f"inest-collect-demos: error: {error}", file=sys.stderr)
        return 2
    failed = len(metadata["failed_seeds"])
    print(
        f"wrote {len(metadata['episodes']['train'])} train + {len(metadata['episodes']['valid'])} valid "
        f"demonstrations to {args.out} (the expert missed {failed} layout{'' if failed == 1 else 's'}, skipped)"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
