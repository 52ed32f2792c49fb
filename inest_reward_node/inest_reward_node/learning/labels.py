"""`inest-label-clips`: a person's stage labels, a few frames per episode, turned into a labelled
clip file that calibration fits the stage evidence on (`inest-pretrain --clips`), with no
simulator involved: the labelling path of a robot.

The frames come from a clip file (inest-record-clips: a policy's rollouts) or from an MCAP
recording of the robot's camera (`inest-record --images`, with the reward node running: its
`reward` messages say where each episode starts). The label file is CSV, one row per change
of stage, `episode,frame,blocks`: from frame `frame` of episode `episode` (both counted from 0)
on, `blocks` blocks are placed in order (a block pushed back out: a row with fewer). An episode
starts with 0 blocks; only the episodes the file names are kept. `--template FILE` writes a
file with one `episode,0,0` row per episode and its frame count, to fill in, and `--sheets DIR`
one contact sheet per episode (every frame, numbered) to read the frame numbers from.
"""

from __future__ import annotations

import argparse
import csv
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np
from inest_common.files import write_atomic
from inest_common.settings import OneLineParser
from inest_sim_node.scoring import NUM_BLOCKS

from ..runtime.images import RESIZE_MODES, ImageRejected, decode_image
from .clips import Clip, ClipError, save_clips

LABEL_COLUMNS = ("episode", "frame", "blocks")


class LabelError(ValueError):
    """A label file, or a recording, that cannot be used; the message names the line or topic."""


def read_labels(path: str | Path) -> dict[int, list[tuple[int, int]]]:
    """episode -> [(frame, blocks), ...] sorted by frame, from the CSV label file."""
    labels: dict[int, list[tuple[int, int]]] = defaultdict(list)
    try:
        with open(path, newline="") as handle:
            rows = [row for row in csv.reader(handle) if row and not row[0].lstrip().startswith("#")]
    except OSError as error:
        raise LabelError(f"cannot read {path}: {error.strerror}") from None
    if rows and [cell.strip() for cell in rows[0]] == list(LABEL_COLUMNS):
        rows = rows[1:]
    for number, row in enumerate(rows, start=1):
        try:
            episode, frame, blocks = (int(cell) for cell in row)
        except ValueError:
            raise LabelError(f"{path}: row {number} {row} is not three integers {','.join(LABEL_COLUMNS)}") from None
        if episode < 0 or frame < 0 or not 0 <= blocks <= NUM_BLOCKS:
            raise LabelError(f"{path}: row {number}: episode and frame >= 0, blocks in 0..{NUM_BLOCKS}, got {row}")
        labels[episode].append((frame, blocks))
    if not labels:
        raise LabelError(f"{path}: no labels")
    return {episode: sorted(changes) for episode, changes in labels.items()}


def labelled_clips(episodes: list[np.ndarray], labels: dict[int, list[tuple[int, int]]]) -> list[Clip]:
    """The labelled episodes as clips: each frame's blocks from the last change at or before it.
    Who holds which block is not labelled (the 6-subtask scheme's grasp stays unknown: False)."""
    clips = []
    for episode, changes in sorted(labels.items()):
        if episode >= len(episodes):
            raise LabelError(f"labels name episode {episode}; the frames hold episodes 0..{len(episodes) - 1}")
        frames = episodes[episode]
        progress = np.zeros(len(frames), dtype=np.int64)
        for frame, blocks in changes:
            if frame >= len(frames):
                raise LabelError(f"episode {episode} has {len(frames)} frames; a label names frame {frame}")
            progress[frame:] = blocks
        clips.append(Clip(frames, progress, np.zeros(len(frames), dtype=bool)))
    return clips


def clip_file_episodes(path: Path) -> tuple[list[np.ndarray], str]:
    """The frames of every episode of a clip file, and its camera."""
    try:
        with np.load(path) as data:
            count = sum(1 for key in data.files if key.startswith("frames_"))
            return [data[f"frames_{index}"] for index in range(count)], str(data["view"])
    except (OSError, KeyError, ValueError) as error:
        raise ClipError(f"{path}: not a clip file of inest-record-clips ({error})") from error


def mcap_episodes(path: Path, namespace: str, image_topic: str, size: int, resize: str) -> list[np.ndarray]:
    """The camera frames of one stream of an MCAP recording, split into episodes where the
    stream's reward says a new one began (Reward.episode_frame 1), each fitted to `size` pixels."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    prefix = f"/{namespace.strip('/')}" if namespace.strip("/") else ""
    camera, reward = f"{prefix}/{image_topic.strip('/')}", f"{prefix}/reward"
    frames: dict[int, np.ndarray] = {}
    starts: list[int] = []
    try:
        with open(path, "rb") as handle:
            reader = make_reader(handle, decoder_factories=[DecoderFactory()])
            for _, channel, _, msg in reader.iter_decoded_messages([camera, reward], log_time_order=True):
                stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
                if channel.topic == reward:
                    if msg.episode_frame == 1:
                        starts.append(stamp)
                    continue
                try:
                    frames[stamp] = decode_image(msg.encoding, msg.height, msg.width, msg.step, msg.data, size, resize)
                except ImageRejected as error:
                    raise LabelError(f"{path}: a {camera} frame is unusable: {error}") from None
    except OSError as error:
        raise LabelError(f"cannot read {path}: {error.strerror}") from None
    if not frames:
        raise LabelError(f"{path} holds no frames on {camera} (record with inest-record --images)")
    if not starts:
        raise LabelError(f"{path} holds no {reward} message starting an episode: record with the reward node running")
    stamps = sorted(frames)
    bounds = np.searchsorted(stamps, sorted(starts))
    pieces = np.split(np.arange(len(stamps)), bounds)
    return [np.stack([frames[stamps[i]] for i in piece]) for piece in pieces if len(piece)]


def write_template(path: Path, episodes: list[np.ndarray]) -> None:
    lines = [
        "# episode,frame,blocks: from this frame of the episode on, this many blocks are placed in order",
        ",".join(LABEL_COLUMNS),
    ]
    for index, frames in enumerate(episodes):
        lines += [f"# episode {index}: {len(frames)} frames", f"{index},0,0"]
    write_atomic(path, lambda temporary: temporary.write_text("\n".join(lines) + "\n"))


SHEET_COLUMNS = 10
SHEET_TILE = 96  # pixels a frame is drawn at


def write_sheets(folder: Path, episodes: list[np.ndarray], names: list[str] | None = None) -> None:
    """<name>.png per episode (episode_<i> unless named): its frames in rows of SHEET_COLUMNS,
    each with its number."""
    import cv2

    folder.mkdir(parents=True, exist_ok=True)
    names = names or [f"episode_{index}" for index in range(len(episodes))]
    for name, frames in zip(names, episodes, strict=True):
        tiles = []
        for number, frame in enumerate(frames):
            tile = cv2.resize(np.ascontiguousarray(frame), (SHEET_TILE, SHEET_TILE), interpolation=cv2.INTER_NEAREST)
            cv2.putText(tile, str(number), (3, 14), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (255, 255, 255), 2)
            cv2.putText(tile, str(number), (3, 14), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1)
            tiles.append(tile)
        tiles += [np.zeros_like(tiles[0])] * (-len(tiles) % SHEET_COLUMNS)
        rows = [np.hstack(tiles[start : start + SHEET_COLUMNS]) for start in range(0, len(tiles), SHEET_COLUMNS)]
        cv2.imwrite(str(folder / f"{name}.png"), cv2.cvtColor(np.vstack(rows), cv2.COLOR_RGB2BGR))


def main(argv: list[str] | None = None) -> int:
    parser = OneLineParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("source", type=Path, help="a clip file (.npz) or an MCAP recording (.mcap)")
    parser.add_argument("labels", type=Path, nargs="?", help="the CSV label file")
    parser.add_argument("--out", type=Path, help="the labelled clip file to write")
    parser.add_argument("--template", type=Path, help="write a label file to fill in, one row per episode, and exit")
    parser.add_argument("--sheets", type=Path, help="with --template: also a numbered contact sheet per episode here")
    recording = parser.add_argument_group("MCAP recordings")
    recording.add_argument("--namespace", default="", help="the stream's namespace, e.g. sim0 or arm1")
    recording.add_argument("--image-topic", default="camera/ego/image_raw", help="the camera, under the namespace")
    recording.add_argument("--view", default="ego", help="the camera's name in the clip file (the model's view)")
    recording.add_argument("--image-size", type=int, default=96, help="frames are fitted to this (the model's)")
    recording.add_argument("--resize", choices=RESIZE_MODES, default="crop")
    args = parser.parse_args(argv)
    if args.template is None and (args.labels is None or args.out is None):
        parser.error("give LABELS and --out, or --template FILE")
    try:
        if args.source.suffix == ".mcap":
            episodes = mcap_episodes(args.source, args.namespace, args.image_topic, args.image_size, args.resize)
            view = args.view
        else:
            episodes, view = clip_file_episodes(args.source)
        if args.template is not None:
            write_template(args.template, episodes)
            if args.sheets is not None:
                write_sheets(args.sheets, episodes)
            sheets = f", their frames numbered in {args.sheets}/" if args.sheets is not None else ""
            print(f"wrote {args.template}: {len(episodes)} episodes to label{sheets}")
            return 0
        clips = labelled_clips(episodes, read_labels(args.labels))
        save_clips(args.out, clips, view, f"{args.source.name} labelled by {args.labels.name}", labelled_by="file")
    except (LabelError, ClipError) as error:
        print(f"inest-label-clips: {error}", file=sys.stderr)
        return 2
    labelled = sum(len(clip.frames) for clip in clips)
    print(f"wrote {args.out}: {len(clips)} labelled episodes, {labelled} frames (inest-pretrain --clips {args.out})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
