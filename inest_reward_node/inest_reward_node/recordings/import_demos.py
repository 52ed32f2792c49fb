"""`inest-import-demos`: a robot's recordings as a demonstration dataset that inest-pretrain reads.

SOURCE is one or more ROS 2 bags (rosbag2 folders, or .mcap / .db3 files; one per demonstration,
or one cut by --episode-times), a LeRobot v3 dataset folder, or a folder of video files (one per
demonstration; with two cameras, one subfolder per camera). --camera maps the dataset's cameras
to the recording's: `ego=TOPIC` for a bag, `ego=VIDEO_KEY` for LeRobot, `ego=SUBFOLDER` for
videos; `allo=...` adds the second (scene) camera. Every camera is resampled to --rate frames per
second (the simulator's control rate) and fitted to --image-size. Subtask ends come from the
LeRobot dataset where it has them; otherwise label them with inest-label-demos.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Iterator
from pathlib import Path

from inest_common.progress import track
from inest_common.settings import OneLineParser
from inest_sim_node.config import EnvConfig, WorldConfig
from inest_sim_node.dataset import VIEWS, DatasetError

from ..runtime.images import RESIZE_MODES
from .bags import STAMP_SOURCES, Bag, bag_episodes, read_episode_times
from .lerobot import lerobot_episodes, read_info
from .videos import video_episodes
from .writer import RecordedEpisode, RecordingError, check_out, write_recorded_dataset

KINDS = ("bag", "lerobot", "videos")
BAG_SUFFIXES = (".mcap", ".db3")


def source_kind(sources: list[Path]) -> str:
    """What the sources are, from what they hold."""
    for source in sources:
        if not source.exists():
            raise RecordingError(f"{source} does not exist")
    first = sources[0]
    if first.suffix in BAG_SUFFIXES or (first / "metadata.yaml").is_file():
        return "bag"
    if (first / "meta" / "info.json").is_file():
        return "lerobot"
    if first.is_dir():
        return "videos"
    raise RecordingError(f"{first}: not a ROS 2 bag, a LeRobot dataset or a folder of videos")


def parse_cameras(specs: list[str]) -> dict[str, str]:
    cameras = {}
    for spec in specs:
        view, _, name = spec.partition("=")
        if view not in VIEWS or not name:
            raise RecordingError(f"--camera {spec!r}: expected ego=NAME or allo=NAME")
        cameras[view] = name
    return dict(sorted(cameras.items(), key=lambda item: VIEWS.index(item[0])))


def default_cameras(kind: str, sources: list[Path]) -> dict[str, str]:
    """The one camera a recording has, as the ego view; several: the user must name them."""
    if kind == "videos":
        return {"ego": ""}
    if kind == "lerobot":
        info = read_info(sources[0])
        found = sorted(key for key, feature in info.get("features", {}).items() if feature.get("dtype") == "video")
    else:
        found = Bag(sources[0], {}).image_topics
    if len(found) != 1:
        raise RecordingError(f"{sources[0]} has cameras {', '.join(found) or 'none'}: name one with --camera ego=NAME")
    return {"ego": found[0]}


def main(argv: list[str] | None = None) -> int:
    parser = OneLineParser(
        prog="inest-import-demos", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("sources", type=Path, nargs="+", metavar="SOURCE")
    parser.add_argument("--out", type=Path, required=True, help="the dataset folder to create")
    parser.add_argument("--from", dest="kind", choices=KINDS, help="what SOURCE is (default: read from it)")
    parser.add_argument("--camera", action="append", default=[], help="VIEW=NAME, VIEW ego or allo (repeatable)")
    parser.add_argument("--rate", type=float, default=WorldConfig.control_hz, help="frames per second of the dataset")
    parser.add_argument("--image-size", type=int, default=EnvConfig.image_size)
    parser.add_argument("--resize", choices=RESIZE_MODES, default="crop")
    parser.add_argument("--valid-fraction", type=float, default=0.2, help="the last episodes kept for validation")
    bags = parser.add_argument_group("ROS 2 bags")
    bags.add_argument("--episode-times", type=Path, help="CSV episode,start,end (s since the bag's start)")
    bags.add_argument(
        "--stamps", choices=STAMP_SOURCES, default="header", help="place frames by header or receive time"
    )
    args = parser.parse_args(argv)
    began = time.monotonic()
    try:
        if args.rate <= 0 or args.image_size < 8 or not 0 <= args.valid_fraction < 1:
            raise RecordingError("--rate must be > 0, --image-size >= 8, --valid-fraction in [0, 1)")
        check_out(args.out)
        kind = args.kind or source_kind(args.sources)
        if kind != "bag" and len(args.sources) != 1:
            raise RecordingError(f"a {kind} source is one folder; {len(args.sources)} were given")
        cameras = parse_cameras(args.camera) or default_cameras(kind, args.sources)
        episodes: Iterator[RecordedEpisode]
        if kind == "bag":
            count = len(read_episode_times(args.episode_times)) if args.episode_times else len(args.sources)
            episodes = bag_episodes(
                args.sources, cameras, args.rate, args.image_size, args.resize, args.episode_times, args.stamps
            )
        elif kind == "lerobot":
            count = int(read_info(args.sources[0]).get("total_episodes", 0)) or None
            episodes = lerobot_episodes(args.sources[0], cameras, args.rate, args.image_size, args.resize)
        else:
            count = None
            episodes = video_episodes(args.sources[0], cameras, args.rate, args.image_size, args.resize)
        record = {
            "source": {"kind": kind, "paths": [str(s) for s in args.sources], "episode_times": args.episode_times
                       and str(args.episode_times), "stamps": args.stamps},
            "cameras": cameras,
            "rate": args.rate,
            "image_size": args.image_size,
            "resize": args.resize,
            "valid_fraction": args.valid_fraction,
        }  # fmt: skip
        metadata = write_recorded_dataset(
            args.out, track(episodes, total=count, desc="importing", unit="demo"), record, args.valid_fraction
        )
    except (RecordingError, DatasetError, OSError) as error:
        message = error if not isinstance(error, OSError) else f"{error.filename or ''}: {error.strerror}"
        print(f"inest-import-demos: error: {message}", file=sys.stderr)
        return 2
    split = metadata["episodes"]
    frames = sum(entry["frames"] for part in split.values() for entry in part)
    mapped = ", ".join(f"{view}={name or args.sources[0]}" for view, name in cameras.items())
    labelled = (
        f"subtask ends from the recording ({metadata['subtask_ends']['subtasks']} per demonstration)"
        if "subtask_ends" in metadata
        else f"no subtask ends: inest-label-demos {args.out} --template ends.csv --sheets sheets/"
    )
    print(
        f"wrote {len(split['train'])} train + {len(split['valid'])} valid demonstrations ({frames} frames at "
        f"{args.rate:g} Hz; {mapped}) to {args.out} in {time.monotonic() - began:.0f} s; {labelled}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
