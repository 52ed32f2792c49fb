"""A person's sparse stage labels, on a policy's clips or on an MCAP recording of a camera,
become a labelled clip file that calibration fits on, and that the model records as file-labelled."""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
from inest_bringup.recording import McapRecording
from inest_interfaces.msg import Reward
from inest_reward_node.learning import labels
from inest_reward_node.learning.calibrate import supervision
from inest_reward_node.learning.clips import Clip, clip_file_labels, load_clips, random_play, save_clips
from inest_reward_node.learning.config import CalibrationConfig, PretrainConfig
from inest_reward_node.learning.pretrain import recalibrate
from rclpy.serialization import serialize_message
from sensor_msgs.msg import Image


def frames(count: int, shade: int) -> np.ndarray:
    return np.full((count, 16, 16, 3), shade, dtype=np.uint8)


def test_sparse_labels_turn_a_policy_s_clips_into_file_labelled_negatives(tmp_path, capsys):
    source = tmp_path / "rollouts.npz"
    clips = [Clip(frames(n, n), np.full(n, 3), np.zeros(n, bool)) for n in (10, 12, 8)]  # simulator says 3
    save_clips(source, clips, "ego", "a policy's rollouts")
    sheets = tmp_path / "sheets"
    assert labels.main([str(source), "--template", str(tmp_path / "template.csv"), "--sheets", str(sheets)]) == 0
    assert sorted(path.name for path in sheets.iterdir()) == ["episode_0.png", "episode_1.png", "episode_2.png"]
    assert cv2.imread(str(sheets / "episode_1.png")).shape == (2 * 96, 10 * 96, 3)  # 12 frames: two rows of ten
    template = (tmp_path / "template.csv").read_text()
    assert "# episode 1: 12 frames" in template and "2,0,0" in template
    (tmp_path / "labels.csv").write_text("episode,frame,blocks\n# red in at 4, out again at 9\n0,4,1\n0,9,0\n2,3,2\n")
    out = tmp_path / "labelled.npz"
    assert labels.main([str(source), str(tmp_path / "labels.csv"), "--out", str(out)]) == 0
    assert "2 labelled episodes, 18 frames" in capsys.readouterr().out
    labelled = load_clips(out, "ego", 16)
    assert labelled[0].progress.tolist() == [0] * 4 + [1] * 5 + [0]  # episode 1 was not labelled: left out
    assert labelled[1].progress.tolist() == [0, 0, 0, 2, 2, 2, 2, 2]
    assert clip_file_labels(out) == (2, "file") and clip_file_labels(source) == (3, "simulator")
    # the model calibrated on them records who labelled what, and that it needs only its own camera
    config = PretrainConfig(
        dataset="d", calibration=CalibrationConfig(random_episodes=0, wrong_order_episodes=0, clips=(str(out),))
    )
    record = supervision(config, demonstrations=100)
    assert record["labelled_episodes"] == 2 and record["simulator_labelled_episodes"] == 0
    assert record["negatives"][f"clips:{out}"] == {"episodes": 2, "labelled_by": "file"}
    # bad labels: one line naming the row, nothing written
    (tmp_path / "bad.csv").write_text("0,4,5\n")
    assert labels.main([str(source), str(tmp_path / "bad.csv"), "--out", str(tmp_path / "x.npz")]) == 2
    assert "row 1: episode and frame >= 0, blocks in 0..3" in capsys.readouterr().err
    (tmp_path / "far.csv").write_text("0,40,1\n")
    assert labels.main([str(source), str(tmp_path / "far.csv"), "--out", str(tmp_path / "x.npz")]) == 2
    assert "episode 0 has 10 frames; a label names frame 40" in capsys.readouterr().err
    assert not (tmp_path / "x.npz").exists()


def test_an_mcap_recording_of_a_camera_splits_into_episodes_where_the_reward_node_began_them(tmp_path):
    path = tmp_path / "robot.mcap"
    recording = McapRecording(
        path, {"/arm1/camera/image_raw": "sensor_msgs/msg/Image", "/arm1/reward": "inest_interfaces/msg/Reward"}
    )
    for index in range(7):  # episodes begin at frames 0 and 4
        stamp = (index + 1) * 100_000_000
        image = Image(height=20, width=24, encoding="rgb8", step=72, data=bytes([index * 10]) * (20 * 72))
        reward = Reward(episode_frame=1 if index in (0, 4) else index + 1)
        for msg in (image, reward):
            msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp, 1_000_000_000)
        recording.write("/arm1/camera/image_raw", serialize_message(image), stamp, stamp)
        recording.write("/arm1/reward", serialize_message(reward), stamp, stamp)
    recording.close()
    episodes = labels.mcap_episodes(path, "arm1", "camera/image_raw", 16, "crop")
    assert [len(episode) for episode in episodes] == [4, 3] and episodes[0].shape[1:] == (16, 16, 3)
    assert episodes[1][0, 0, 0, 0] == 40  # the fifth frame starts the second episode
    (tmp_path / "labels.csv").write_text("1,2,1\n")
    out = tmp_path / "robot.npz"
    argv = [str(path), str(tmp_path / "labels.csv"), "--out", str(out), "--namespace", "arm1"]
    assert labels.main([*argv, "--image-topic", "camera/image_raw", "--image-size", "16"]) == 0
    assert load_clips(out, "ego", 16)[0].progress.tolist() == [0, 0, 1]
    assert labels.main([*argv, "--image-topic", "camera/other", "--image-size", "16"]) == 2


def test_labelled_clips_can_raise_the_thresholds_as_the_simulator_s_random_play_does(tiny_tcc_run, tmp_path):
    """A robot has no simulator to play randomly: the same random-play episodes, labelled in a
    clip file and given with clips_raise_thresholds, calibrate the same thresholds and classifier."""
    config, run = tiny_tcc_run
    played = tmp_path / "random.npz"
    save_clips(played, random_play("ego", 48, 3), "ego", "random play", labelled_by="file")

    def thresholds(name: str, **calibration) -> tuple[list[float], np.ndarray]:
        settings = dataclasses.replace(config.calibration, wrong_order_episodes=0, **calibration)
        settings = dataclasses.replace(settings, stage_head=dataclasses.replace(settings.stage_head, iterations=0))
        model = recalibrate(dataclasses.replace(config, calibration=settings), run / "model", tmp_path / name, False)
        return model.goals(3).thresholds, model.goals(3).stage_classifier.out_weight

    simulator = thresholds("simulator", random_episodes=3)
    robot = thresholds("robot", random_episodes=0, clips=(str(played),), clips_raise_thresholds=True)
    classifier_only = thresholds("classifier-only", random_episodes=0, clips=(str(played),))
    demonstrations_only = thresholds("demonstrations-only", random_episodes=0)
    assert all(np.greater(simulator[0], demonstrations_only[0]))  # random play raised every threshold here
    np.testing.assert_allclose(robot[0], simulator[0])
    np.testing.assert_allclose(robot[1], simulator[1])
    np.testing.assert_allclose(classifier_only[0], demonstrations_only[0])  # without it: demonstrations alone
