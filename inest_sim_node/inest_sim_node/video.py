"""Export a demonstration episode as a GIF or MP4 for a person to watch (`inest-export-video`)."""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np
from inest_common.settings import OneLineParser
from PIL import Image

from .dataset import DatasetError, DemoDataset, Episode

VIEW_CHOICES = ("both", "allo", "ego")


def episode_frames(episode: Episode, view: str = "both", scale: int = 3) -> list[np.ndarray]:
    """RGB frames, enlarged with crisp pixels; "both" puts allocentric left, egocentric right."""
    if view not in VIEW_CHOICES:
        raise ValueError(f"unknown view {view!r}; expected one of {VIEW_CHOICES}")
    if scale < 1:
        raise ValueError(f"scale must be >= 1, got {scale}")
    views = [episode.allo, episode.ego] if view == "both" else [episode.frames(view)]
    frames = np.concatenate(views, axis=2)
    return [cv2.resize(f, None, fx=scale, fy=scale, interpolation=cv2.INTER_NEAREST) for f in frames]


def write_video(frames: Sequence[np.ndarray], path: str | Path, fps: float = 8.0) -> Path:
    """GIF (Pillow) or MP4 (OpenCV), chosen by the file extension."""
    path = Path(path)
    if not frames:
        raise ValueError("no frames to write")
    path.parent.mkdir(parents=True, exist_ok=True)
    suffix = path.suffix.lower()
    if suffix == ".gif":
        images = [Image.fromarray(frame) for frame in frames]
        images[0].save(path, save_all=True, append_images=images[1:], duration=round(1000 / fps), loop=0)
    elif suffix == ".mp4":
        height, width = frames[0].shape[:2]
        writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), fps, (width, height))
        if not writer.isOpened():
            raise RuntimeError(f"OpenCV could not open an MP4 writer for {path}")
        for frame in frames:
            writer.write(cv2.cvtColor(frame, cv2.COLOR_RGB2BGR))
        writer.release()
    else:
        raise ValueError(f"unsupported video format {suffix!r} for {path}; use .gif or .mp4")
    return path


def main(argv: list[str] | None = None) -> int:
    parser = OneLineParser(description=__doc__)
    parser.add_argument("dataset", type=Path, help="dataset folder written by inest-collect-demos")
    parser.add_argument("--out", type=Path, required=True, help="output .gif or .mp4")
    parser.add_argument("--split", default="train", choices=("train", "valid"))
    parser.add_argument("--index", type=int, default=0, help="episode index within the split")
    parser.add_argument("--view", default="both", choices=VIEW_CHOICES)
    parser.add_argument("--scale", type=int, default=3, help="pixel enlargement factor")
    parser.add_argument("--fps", type=float, default=8.0)
    args = parser.parse_args(argv)
    try:
        episode = DemoDataset(args.dataset).load(args.split, args.index)
        path = write_video(episode_frames(episode, args.view, args.scale), args.out, args.fps)
    except (DatasetError, ValueError, IndexError, RuntimeError) as error:
        print(f"inest-export-video: error: {error}", file=sys.stderr)
        return 2
    print(f"wrote {len(episode)} frames (seed {episode.seed}) to {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
