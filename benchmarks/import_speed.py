"""How long a robot session of 50 demonstrations takes to import (`inest-import-demos`).

Writes, with `rosbags`, one MCAP bag as a robot session records it: two cameras at 30 Hz, 640x480
JPEG `sensor_msgs/CompressedImage` (image_transport's `<topic>/compressed`), the scene camera 5 ms
out of phase, 50 expert demonstrations one after another with 2 s of reset between them, and the
file of episode start and end times that cuts it. The frames are the simulator's 96 px renders
scaled up to 640x480 before encoding (the JPEG files are smaller than a real camera's, their
decoding costs the same). Then times the import command as a user runs it, process start to
exit, into 96 px frames at 8 Hz. Target: under 120 s on this machine. Prints one JSON object.
`import_speed.py [--demos 50] [--keep DIR]`
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np
from inest_sim_node.collect import CollectConfig, collect_dataset
from inest_sim_node.dataset import DemoDataset
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

BENCHMARK = "import_speed"
CAMERA_HZ, WIDTH, HEIGHT = 30, 640, 480
SIM_HZ = 8
RESET_S = 2.0
SECOND = 1_000_000_000
TOPICS = {"ego": "/arm/wrist_camera/image_raw/compressed", "allo": "/scene_camera/image_raw/compressed"}
PHASE_NS = {"ego": 0, "allo": 5_000_000}
TARGET_S = 120.0


def jpeg(frame: np.ndarray) -> np.ndarray:
    side = cv2.resize(frame, (WIDTH, WIDTH), interpolation=cv2.INTER_LINEAR)[(WIDTH - HEIGHT) // 2 :][:HEIGHT]
    return np.frombuffer(cv2.imencode(".jpg", cv2.cvtColor(side, cv2.COLOR_RGB2BGR))[1], np.uint8)


def write_session(dataset: DemoDataset, bag: Path, times: Path) -> dict[str, int]:
    store = get_typestore(Stores.ROS2_JAZZY)
    message, header, stamp_type = (
        store.types[name]
        for name in ("sensor_msgs/msg/CompressedImage", "std_msgs/msg/Header", "builtin_interfaces/msg/Time")
    )
    rows, messages, clock = ["episode,start,end"], 0, 0
    with Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        connections = {
            view: writer.add_connection(topic, message.__msgtype__, typestore=store) for view, topic in TOPICS.items()
        }
        for split in ("train", "valid"):
            for index in range(len(dataset.entries(split))):
                episode = dataset.load(split, index)
                encoded = {view: [jpeg(frame) for frame in episode.frames(view)] for view in TOPICS}
                start, duration = clock, (len(episode) - 1) / SIM_HZ
                for tick in range(int(duration * CAMERA_HZ) + 1):
                    for view, connection in connections.items():
                        stamp = SECOND + clock + tick * SECOND // CAMERA_HZ + PHASE_NS[view]
                        frame = min(int((stamp - SECOND - start) * SIM_HZ // SECOND), len(episode) - 1)
                        msg = message(
                            header=header(stamp=stamp_type(sec=stamp // SECOND, nanosec=stamp % SECOND), frame_id=view),
                            format="jpeg",
                            data=encoded[view][frame],
                        )
                        writer.write(connection, stamp, store.serialize_cdr(msg, connection.msgtype))
                        messages += 1
                clock += round((duration + RESET_S) * SECOND)
                rows.append(f"demo_{len(rows):02d},{start / SECOND:.3f},{(start / SECOND + duration + 0.1):.3f}")
    times.write_text("\n".join(rows) + "\n")
    return {"messages": messages, "episodes": len(rows) - 1}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--demos", type=int, default=50)
    parser.add_argument("--keep", type=Path, help="write the demonstrations, bag and dataset here and keep them")
    args = parser.parse_args()
    work = args.keep or Path(tempfile.mkdtemp(prefix="inest-import-"))
    work.mkdir(parents=True, exist_ok=True)
    try:
        demos = work / "demos"
        collect_dataset(demos, CollectConfig(episodes=args.demos, valid_fraction=0.0), show_progress=False)
        bag, times = work / "session", work / "episodes.csv"
        written = write_session(DemoDataset(demos), bag, times)
        command = [str(Path(sys.executable).parent / "inest-import-demos"), str(bag), "--out", str(work / "imported")]
        command += ["--episode-times", str(times)] + [f"--camera={view}={topic}" for view, topic in TOPICS.items()]
        began = time.perf_counter()
        subprocess.run(command, check=True, capture_output=True)
        seconds = time.perf_counter() - began
        imported = DemoDataset(work / "imported")
        frames = sum(entry["frames"] for split in ("train", "valid") for entry in imported.entries(split))
        result = {
            "benchmark": BENCHMARK,
            "demonstrations": written["episodes"],
            "bag_messages": written["messages"],
            "bag_megabytes": round(sum(f.stat().st_size for f in bag.iterdir()) / 2**20, 1),
            "cameras": {view: f"{WIDTH}x{HEIGHT} jpeg at {CAMERA_HZ} Hz" for view in TOPICS},
            "dataset_frames": frames,
            "dataset_rate_hz": SIM_HZ,
            "import_seconds": round(seconds, 1),
            "target_seconds": TARGET_S,
            "meets_target": seconds < TARGET_S,
            "command": "inest-import-demos SESSION --out DATASET --episode-times episodes.csv "
            + " ".join(command[-2:]),
        }
    finally:
        if args.keep is None:
            shutil.rmtree(work, ignore_errors=True)
    print(json.dumps(result))


if __name__ == "__main__":
    main()
