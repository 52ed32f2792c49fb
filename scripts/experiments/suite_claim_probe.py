"""Where a reward's unplaced claims fall on the exploit suite: for every frame on which the
tracker marks a block done that the episode never places, how far that block sticks out below
the goal (world units; a block side is 0.21) and whether the camera shows any of it.

  .venv/bin/python scripts/experiments/suite_claim_probe.py MODEL RUN OUT.json [PART]

MODEL scores with RUN's reward settings (inest-exploit-suite --reward-of RUN), on the suite's
development part unless PART says otherwise. 3 subtasks.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
from inest_reward_node.learning.exploit_check import run_reward_settings
from inest_reward_node.learning.exploit_suite import SUITE_DIR, load_part, suite_file
from inest_reward_node.learning.quality import reward_config, suite_events
from inest_reward_node.runtime.model import load_model
from inest_sim_node.render import PALETTE
from inest_sim_node.subtasks import completed_subtasks
from inest_sim_node.world import BLOCK_COLOURS, pose_goal_gaps

SCHEME = 3


def shows(frame: np.ndarray, colour: str) -> bool:
    return bool((np.abs(frame.astype(int) - PALETTE[colour]).max(-1) <= 30).any())


def main(model_dir: str, run: str, out: str, part_name: str = "development") -> None:
    model = load_model(model_dir)
    options = {"config": reward_config(run_reward_settings(Path(run)))}
    part = load_part(suite_file(SUITE_DIR, part_name))
    claims = []
    for episode, clip, replays in suite_events(model, part, [SCHEME], options):
        done = completed_subtasks(clip.progress, clip.held, SCHEME)
        for k, frames in enumerate(replays[SCHEME].claims()):
            if done[-1] > k:
                continue  # earned in the end: early at worst
            for frame in frames:
                step = min(frame, len(episode.poses) - 1)
                gap = float(pose_goal_gaps(episode.poses[step], part.world)[k])
                claims.append(
                    {
                        "policy": episode.policy,
                        "layout_seed": episode.layout_seed,
                        "subtask": k,
                        "frame": int(frame),
                        "gap": round(gap, 3),
                        "block_in_view": shows(clip.frames[frame], BLOCK_COLOURS[k]),
                        "goal_in_view": shows(clip.frames[frame], "goal"),
                    }
                )
    gaps = np.array([claim["gap"] for claim in claims])
    summary = {
        "model": model_dir,
        "reward_of": run,
        "part": part_name,
        "unplaced_claim_events": len(claims),
        "gap_quartiles": np.percentile(gaps, [25, 50, 75]).round(3).tolist() if len(gaps) else None,
        "share_gap_below_half_block": float(np.mean(gaps < part.world.block_side / 2)) if len(gaps) else None,
        "share_block_in_view": float(np.mean([claim["block_in_view"] for claim in claims])) if claims else None,
        "share_goal_in_view": float(np.mean([claim["goal_in_view"] for claim in claims])) if claims else None,
        "claims": claims,
    }
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    Path(out).write_text(json.dumps(summary, indent=2) + "\n")
    print(json.dumps({key: value for key, value in summary.items() if key != "claims"}, indent=2))


if __name__ == "__main__":
    main(*sys.argv[1:])
