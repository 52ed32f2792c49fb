"""A robot's recordings into demonstration datasets: ROS 2 bags written by `rosbags` (MCAP and
sqlite3, compressed and raw frames), the LeRobot v3 fixture lerobot itself wrote, video folders;
subtask ends from a label file; then pretraining on what was imported."""

from __future__ import annotations

import json

import av
import cv2
import numpy as np
import pytest
from inest_reward_node.learning.pretrain import main as pretrain_main
from inest_reward_node.recordings import import_demos, label_demos
from inest_reward_node.recordings.timeline import pick_frames
from inest_reward_node.runtime.model import load_model
from inest_sim_node.collect import record_episode
from inest_sim_node.dataset import DemoDataset
from inest_sim_node.expert import ScriptedExpert
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from inest_sim_node import EnvConfig, SweepToTopEnv

FIXTURES = __import__("pathlib").Path(__file__).parent / "fixtures"
TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
COMPRESSED, IMAGE = (TYPESTORE.types[f"sensor_msgs/msg/{name}"] for name in ("CompressedImage", "Image"))
HEADER, TIME = TYPESTORE.types["std_msgs/msg/Header"], TYPESTORE.types["builtin_interfaces/msg/Time"]
EGO, ALLO = "/arm/wrist/image_raw/compressed", "/scene/image_raw"
SECOND = 1_000_000_000


def header(stamp: int, frame: str):
    return HEADER(stamp=TIME(sec=stamp // SECOND, nanosec=stamp % SECOND), frame_id=frame)


def jpeg(frame: np.ndarray, stamp: int):
    data = np.frombuffer(cv2.imencode(".jpg", cv2.cvtColor(frame, cv2.COLOR_RGB2BGR))[1], np.uint8)
    return COMPRESSED(header=header(stamp, "wrist"), format="rgb8; jpeg compressed bgr8", data=data)


def bgr8(frame: np.ndarray, stamp: int):
    height, width = frame.shape[:2]
    pixels = np.ascontiguousarray(cv2.cvtColor(frame, cv2.COLOR_RGB2BGR)).reshape(-1)
    return IMAGE(header=header(stamp, "scene"), height=height, width=width, encoding="bgr8", is_bigendian=0,
                 step=width * 3, data=pixels)  # fmt: skip


def write_bag(path, episodes, storage, start=100 * SECOND, gap=2 * SECOND):
    """The episodes' ego frames as JPEG CompressedImage, allo as bgr8 Image 3 ms later, at 8 Hz,
    one after another `gap` apart; returns each episode's (start, end) in seconds of the bag."""
    spans, stamp = [], start
    with Writer(path, version=9, storage_plugin=storage) as writer:
        ego = writer.add_connection(EGO, COMPRESSED.__msgtype__, typestore=TYPESTORE)
        allo = writer.add_connection(ALLO, IMAGE.__msgtype__, typestore=TYPESTORE)
        for episode in episodes:
            first = stamp
            for frame in range(len(episode)):
                for connection, message in ((ego, jpeg(episode.ego[frame], stamp)),
                                            (allo, bgr8(episode.allo[frame], stamp + 3_000_000))):  # fmt: skip
                    data = TYPESTORE.serialize_cdr(message, connection.msgtype)
                    writer.write(connection, message.header.stamp.sec * SECOND + message.header.stamp.nanosec, data)
                stamp += SECOND // 8
            spans.append((max((first - start) / SECOND - 0.05, 0.0), (stamp - start) / SECOND))
            stamp += gap
    return spans


def expert_demonstrations(size: int) -> list:
    """The expert's demonstrations of seeds 0-2 as the simulator saw them: the truth to compare to."""
    env = SweepToTopEnv(config=EnvConfig(image_size=size))
    episodes = [record_episode(env, ScriptedExpert(), seed) for seed in range(3)]
    env.close()
    assert all(episode is not None for episode in episodes)
    return episodes


@pytest.fixture(scope="module")
def simulated():
    return expert_demonstrations(48)


def mean_error(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a.astype(np.int16) - b.astype(np.int16)).mean())


def test_pick_frames_takes_each_camera_s_latest_frame_at_the_dataset_s_rate():
    picks = pick_frames({"ego": np.arange(31) * SECOND // 30, "allo": np.arange(11) * SECOND // 10 + 5}, 8)
    assert len(picks.seconds) == 9 and picks.seconds[-1] == pytest.approx(1.0)  # 0 .. 1 s at 8 Hz
    assert picks.frames["ego"][:3].tolist() == [0, 3, 7]  # 30 Hz frames at or before 0, 0.125, 0.25 s
    assert picks.frames["allo"][:3].tolist() == [0, 1, 2]
    with pytest.raises(ValueError, match="do not overlap"):
        pick_frames({"ego": np.array([0, 1]), "allo": np.array([5 * SECOND])}, 8)


def test_bags_in_both_storages_import_as_the_demonstrations_they_recorded_and_a_label_file_cuts_them(
    simulated, tmp_path, capsys
):
    bags = []
    for index, (episode, storage) in enumerate(zip(simulated, (StoragePlugin.MCAP, StoragePlugin.SQLITE3,
                                                                StoragePlugin.MCAP), strict=True)):  # fmt: skip
        bags.append(tmp_path / f"demo_{index}")
        write_bag(bags[-1], [episode], storage)
    out = tmp_path / "imported"
    argv = [*map(str, bags), "--out", str(out), "--camera", f"ego={EGO}", "--camera", f"allo={ALLO}"]
    assert import_demos.main([*argv, "--image-size", "48", "--valid-fraction", "0.34"]) == 0
    assert "2 train + 1 valid demonstrations" in capsys.readouterr().out
    dataset = DemoDataset(out)
    assert dataset.names() == ["demo_0", "demo_1", "demo_2"]
    for index, split in enumerate(("train", "train", "valid")):
        imported, truth = dataset.load(split, index % 2), simulated[index]
        assert len(imported) == len(truth) and imported.views == ("ego", "allo") and imported.progress is None
        assert mean_error(imported.ego, truth.ego) < 3  # JPEG's loss
        assert mean_error(imported.allo, truth.allo) == 0  # raw frames are exact
        assert imported.timestamps[1] == pytest.approx(0.125)
    # the label file: template, contact sheets, a person's rows, applied
    template, sheets = tmp_path / "ends.csv", tmp_path / "sheets"
    assert label_demos.main([str(out), "--template", str(template), "--sheets", str(sheets)]) == 0
    assert "9 rows to fill in; contact sheets (allo camera)" in capsys.readouterr().out
    assert sorted(path.name for path in sheets.iterdir()) == ["demo_0.png", "demo_1.png", "demo_2.png"]
    filled = template.read_text()
    for index, episode in enumerate(simulated):
        for subtask, end in enumerate(episode.ends[3]):
            filled = filled.replace(f"demo_{index},{subtask},\n", f"demo_{index},{subtask},{end}\n")
    template.write_text(filled)
    assert label_demos.main([str(out), str(template)]) == 0
    assert "labelled 3 demonstrations" in capsys.readouterr().out and "(9 rows)" not in filled
    dataset = DemoDataset(out)
    for index, split in enumerate(("train", "train", "valid")):
        imported, truth = dataset.load(split, index % 2), simulated[index]
        assert np.array_equal(imported.progress, truth.progress)
        assert all(np.array_equal(imported.labels[s], truth.labels[s]) for s in (1, 3))
        assert 6 not in imported.labels  # three ends per demonstration cut the 1- and 3-subtask schemes
    # pretraining reads them and records who cut them
    run = tmp_path / "run"
    argv = [str(out), "--out", str(run), "--image-size", "48", "--iterations", "4", "--videos-per-batch", "2"]
    argv += ["--frames-per-video", "8", "--validate-every", "2", "--random-episodes", "0"]
    assert pretrain_main([*argv, "--wrong-order-episodes", "0", "--stage-head-iterations", "4"]) == 0
    model = load_model(run / "model")
    assert sorted(model.subtasks) == [1, 3]
    segmented = model.metadata.supervision["demonstrations"]["segmented_by"]
    assert segmented.startswith("label file ends.csv (9 rows")


def test_one_bag_is_cut_into_episodes_by_a_file_of_start_and_end_times(simulated, tmp_path, capsys):
    spans = write_bag(tmp_path / "session", simulated, StoragePlugin.MCAP)
    bag = next((tmp_path / "session").glob("*.mcap"))  # a bare .mcap file reads as well
    times = tmp_path / "times.csv"
    times.write_text("episode,start,end\n" + "".join(f"take_{i},{a:.3f},{b:.3f}\n" for i, (a, b) in enumerate(spans)))
    out = tmp_path / "cut"
    argv = [str(bag), "--out", str(out), "--camera", f"ego={EGO}", "--image-size", "48", "--episode-times", str(times)]
    assert import_demos.main(argv) == 0
    dataset = DemoDataset(out)
    assert dataset.names() == ["take_0", "take_1", "take_2"]
    lengths = [entry["frames"] for split in ("train", "valid") for entry in dataset.entries(split)]
    assert lengths == [len(episode) for episode in simulated] and dataset.load("train", 0).allo is None


def test_the_lerobot_fixture_imports_with_its_subtask_ends_and_frames(tmp_path, capsys):
    """tests/fixtures/lerobot_sweep was written by lerobot 0.4.4's LeRobotDataset from seeds 0-2
    at 96 px with AV1 video (scripts/fixtures/make_lerobot_fixture.sh)."""
    simulated = expert_demonstrations(96)
    out = tmp_path / "lerobot"
    cameras = ["--camera", "ego=observation.images.ego", "--camera", "allo=observation.images.allo"]
    assert import_demos.main([str(FIXTURES / "lerobot_sweep"), "--out", str(out), *cameras]) == 0
    assert "subtask ends from the recording (3 per demonstration)" in capsys.readouterr().out
    dataset = DemoDataset(out)
    assert dataset.segmented_by() == "the recording's own subtask annotation (lerobot)"
    for index, split in enumerate(("train", "train", "valid")):
        imported, truth = dataset.load(split, index % 2), simulated[index]
        assert len(imported) == len(truth) and imported.ends[3].tolist() == truth.ends[3].tolist()
        # AV1's loss is 2-3 levels; a frame off by one is 5-12
        assert mean_error(imported.ego, truth.ego) < 3 and mean_error(imported.allo, truth.allo) < 3


def write_video(path, frames: np.ndarray, fps: int) -> None:
    with av.open(str(path), "w") as container:
        stream = container.add_stream("libx264", rate=fps)
        stream.width, stream.height, stream.pix_fmt = frames.shape[2], frames.shape[1], "yuv420p"
        for frame in frames:
            container.mux(stream.encode(av.VideoFrame.from_ndarray(frame, format="rgb24")))
        container.mux(stream.encode())


def test_a_folder_of_videos_per_camera_is_resampled_to_the_dataset_s_rate(simulated, tmp_path, capsys):
    for camera in ("top", "wrist"):
        (tmp_path / "videos" / camera).mkdir(parents=True)
    for index, episode in enumerate(simulated[:2]):
        slow = np.repeat(episode.allo, 2, axis=0)  # a 16 fps camera: every frame twice
        write_video(tmp_path / "videos" / "top" / f"take_{index}.mp4", slow, 16)
        write_video(tmp_path / "videos" / "wrist" / f"take_{index}.mp4", np.repeat(episode.ego, 2, axis=0), 16)
    out = tmp_path / "videos-dataset"
    argv = [str(tmp_path / "videos"), "--out", str(out), "--camera", "ego=wrist", "--camera", "allo=top"]
    assert import_demos.main([*argv, "--image-size", "48", "--valid-fraction", "0.5"]) == 0
    dataset = DemoDataset(out)
    first = dataset.load("train", 0)
    assert len(first) == len(simulated[0]) and mean_error(first.allo, simulated[0].allo) < 4
    (tmp_path / "videos" / "top" / "take_1.mp4").unlink()
    assert import_demos.main([*argv, "--out", str(tmp_path / "again")]) == 2
    assert "hold different demonstrations: take_1" in capsys.readouterr().err


def test_bad_recordings_and_label_rows_are_one_line_each_and_write_nothing(simulated, tmp_path, capsys):
    bags = [tmp_path / "a", tmp_path / "b"]
    for bag, episode in zip(bags, simulated, strict=False):
        write_bag(bag, [episode], StoragePlugin.SQLITE3)

    def refused(argv: list[str], *expected: str) -> None:
        assert import_demos.main(argv) == 2
        error = capsys.readouterr().err
        assert error.count("\n") == 1 and all(text in error for text in expected), error

    out = str(tmp_path / "out")
    refused([*map(str, bags), "--out", out], "has cameras /arm/wrist/image_raw/compressed, /scene/image_raw")
    refused([*map(str, bags), "--out", out, "--camera", "ego=/nope"], "no Image or CompressedImage topic '/nope'")
    refused([*map(str, bags), "--out", out, "--camera", "eye=/nope"], "expected ego=NAME or allo=NAME")
    refused([str(tmp_path / "missing"), "--out", out], "missing does not exist")
    old = tmp_path / "old-lerobot"
    (old / "meta").mkdir(parents=True)
    (old / "meta" / "info.json").write_text(json.dumps({"codebase_version": "v2.1"}))
    refused([str(old), "--out", out], "is a LeRobot v2.1 dataset; this reads v3")
    refused([*map(str, bags), "--out", str(tmp_path), "--camera", f"ego={EGO}"], "exists; choose another")
    assert not (tmp_path / "out").exists() and not (tmp_path / "out.partial").exists()
    assert import_demos.main([*map(str, bags), "--out", out, "--camera", f"ego={EGO}", "--image-size", "48"]) == 0
    capsys.readouterr()
    metadata = (tmp_path / "out" / "metadata.json").read_bytes()
    length = len(simulated[0])
    rows = tmp_path / "rows.csv"
    rows.write_text(
        "episode,subtask,frame\n"
        "a,0,10\na,1,5\na,2,20\n"  # subtask 1 ends before subtask 0
        f"b,0,3\nb,1,9\nb,1,11\nb,2,{length + 40}\n"  # doubled, and past b's end
        "c,0,4\n"  # no such episode
    )
    assert label_demos.main([out, str(rows)]) == 2
    errors = capsys.readouterr().err.splitlines()
    assert any("rows.csv line 7: episode b subtask 1 is given twice (line 6)" in line for line in errors)
    assert any(f"line 8: frame {length + 40} is past episode b's end" in line for line in errors)
    assert any("line 9: no episode 'c' in the dataset" in line for line in errors)
    assert any("line 3: episode a subtask 1 ends on frame 5, not after subtask 0 (frame 10, line 2)" in line
               for line in errors)  # fmt: skip
    assert any("episode b lacks the end of subtask 2" in line for line in errors)
    assert errors[-1] == "inest-label-demos: 5 problem(s); nothing written"
    assert (tmp_path / "out" / "metadata.json").read_bytes() == metadata
    assert pretrain_main([out, "--out", str(tmp_path / "run")]) == 2
    assert "no subtask ends: label them with inest-label-demos" in capsys.readouterr().err


def test_a_session_recorded_over_the_graph_imports_as_the_takes_the_operator_kept(graph, tmp_path, capsys):
    """The rehearsal's recording: a lockstep simulator node sending JPEG cameras, inest-record,
    the teleoperation stand-in keeping two takes; the times file it writes cuts the bag into
    exactly those takes, frame for frame as its own copy of the simulator saw them."""
    import signal
    import sys

    graph.start("sim", "inest-sim-node", "--ros-args", "-r", "__ns:=/sim0", "-p", "mode:=lockstep",
                "-p", "image_transport:=compressed", "-p", "max_steps:=150", "-p", "publish_clock:=false")  # fmt: skip
    recorder = graph.start(
        "record", sys.executable, "-m", "inest_bringup.recorder", str(tmp_path / "session.mcap"),
        "--namespaces", "sim0", "--images", "--image-transport", "compressed",
    )  # fmt: skip
    times, ends = tmp_path / "times.csv", tmp_path / "ends.csv"
    teleop = graph.start(
        "teleop", "inest-teleop-standin", "--episodes", "2", "--times", str(times), "--ends", str(ends)
    )
    assert teleop.wait(120) == 0, graph.log("teleop") + graph.log("sim")
    recorder.send_signal(signal.SIGINT)
    assert recorder.wait(60) == 0, graph.log("record")
    out = tmp_path / "imported"
    cameras = [f"--camera={view}=/sim0/camera/{view}/image_raw/compressed" for view in ("ego", "allo")]
    argv = [str(tmp_path / "session.mcap"), "--out", str(out), "--episode-times", str(times), *cameras]
    assert import_demos.main([*argv, "--valid-fraction", "0.5"]) == 0, capsys.readouterr().err
    dataset = DemoDataset(out)
    assert dataset.names() == ["take_000", "take_001"]
    true_ends = [line.split(",") for line in ends.read_text().splitlines()[1:]]
    env = SweepToTopEnv(config=EnvConfig(max_steps=150))
    for index, split in enumerate(("train", "valid")):
        take = dataset.load(split, 0)
        assert len(take) == int(true_ends[3 * index + 2][2]) + 1  # the take ends where its last block counts
        env.reset(seed=int(graph.log("teleop").split(f"take_00{index}: seed ")[1].split(",")[0]))
        assert mean_error(take.allo[0], env.render_camera("allo", 96)) < 3  # its first frame: the reset layout
    env.close()
