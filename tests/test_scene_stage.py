"""A stage head on the scene (allocentric) camera beside the egocentric encoder: fitted by
`inest-pretrain --recalibrate`, fed both cameras' frames in training, in the quality report and
in the reward node, whose streams pair the two cameras' frames by stamp."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys

import numpy as np
import pytest
from foreign_camera import PERIOD_NS
from inest_agent_node.envs import LEARNED_STAGE, STAGE_FRAME_KEY, build_env
from inest_interfaces.msg import Reward
from inest_reward_node.learning import pretrain
from inest_reward_node.learning.config import CalibrationConfig
from inest_reward_node.learning.data import load_demos
from inest_reward_node.learning.quality import evaluate, load_stage_frames
from inest_reward_node.runtime.config import RewardConfig
from inest_reward_node.runtime.intrinsic import IntrinsicConfig
from inest_reward_node.runtime.model import load_model
from inest_reward_node.runtime.rewards import RewardScorer, Steps
from inest_reward_node.runtime.serving import StreamScorer
from inest_reward_node.runtime.stage_head import StageHeadConfig
from test_graph import FOREIGN_CAMERA, reward_node_args, sim_node_args

from inest_agent_node.config import TrainConfig

PIXELS = RewardConfig(stage_evidence="pixels")  # the confirmed tracker, reading the head (what auto resolves to)
EMBEDDING = RewardConfig(stage_evidence="embedding")


@pytest.fixture(scope="module")
def scene_model(tiny_tcc_run, tmp_path_factory):
    """The tiny model's encoder, recalibrated with a stage head on the allocentric camera."""
    config, run_dir = tiny_tcc_run
    out = tmp_path_factory.mktemp("scene")
    arguments = [
        config.dataset,
        "--out",
        str(out),
        "--recalibrate",
        str(run_dir / "model"),
        "--stage-head-view",
        "allo",
        "--stage-head-iterations",
        "30",
        "--stage-head-image-size",
        "32",
        "--random-episodes",
        "3",
        "--wrong-order-episodes",
        "2",
        "--stage-head-subtasks",
        "3",
    ]
    assert pretrain.main(arguments) == 0
    return out / "model", arguments


def demo_frames(dataset, view: str, limit: int = 1) -> list[np.ndarray]:
    return [demo.frames for demo in load_demos(dataset, "valid", view, 48, limit, progress_bar=False)]


def test_recalibration_keeps_the_encoder_and_fits_a_head_on_the_scene_camera(tiny_tcc_run, scene_model, capsys):
    config, run_dir = tiny_tcc_run
    folder, arguments = scene_model
    source, model = load_model(run_dir / "model"), load_model(folder)
    frames = demo_frames(config.dataset, "ego")[0]
    np.testing.assert_array_equal(source.embed(frames), model.embed(frames))  # the same trained encoder
    np.testing.assert_array_equal(source.goals(3).goals, model.goals(3).goals)  # same demonstrations
    head = model.goals(3).stage_head.config
    assert model.view == "ego" and head.view == "allo" and head.image_size == 32
    # only the scheme asked for got a head; the others read the embedding (what auto resolves to)
    assert model.goals(1).stage_head is None and model.goals(6).stage_head is None
    assert RewardScorer(model, 1).evidence == "embedding" and RewardScorer(model, 3).evidence == "pixels"
    assert model.metadata.training["recalibrated_from"] == str(run_dir / "model")
    assert model.metadata.training["iterations"] == source.metadata.training["iterations"]
    capsys.readouterr()
    assert pretrain.main(arguments) == 2  # the folder holds a model already: refused, nothing overwritten
    error = capsys.readouterr().err
    assert "already holds a model" in error and error.count("\n") == 1
    with pytest.raises(ValueError, match="unknown view 'top'"):  # pretraining knows the simulator's cameras
        dataclasses.replace(config, calibration=CalibrationConfig(stage_head=StageHeadConfig(view="top")))
    assert StageHeadConfig(view="wrist").view == "wrist"  # a model's camera names are the user's


def test_the_scorer_needs_the_scene_frame_of_every_step(tiny_tcc_run, scene_model):
    config, _ = tiny_tcc_run
    model = load_model(scene_model[0])
    ego, allo = demo_frames(config.dataset, "ego")[0], demo_frames(config.dataset, "allo")[0]
    scorer = RewardScorer(model, 3, num_envs=2, config=PIXELS)
    assert scorer.stage_camera == "allo"
    assert RewardScorer(model, 3).stage_camera == "allo"  # the default (auto) reads the head when there is one
    assert RewardScorer(model, 3, config=EMBEDDING).stage_camera is None  # the classifier reads no second camera
    with pytest.raises(ValueError, match="reads the 'allo' camera"):
        scorer.score(ego[:2])
    scorer.score(ego[:2], stage_frames=allo[:2])
    head = model.goals(3).stage_head
    assert not np.allclose(head.at_least(ego), head.at_least(allo))  # it does look at the frames it is given


def test_training_and_the_quality_report_see_both_cameras(tiny_tcc_run, scene_model, tmp_path):
    config, _ = tiny_tcc_run
    folder = scene_model[0]
    train = TrainConfig(
        reward="inest", model=str(folder), intrinsic=IntrinsicConfig(mode="none"), learned_reward=PIXELS
    )
    env = build_env(train, num_envs=2, evaluation=True)
    env.reset()
    for _ in range(3):
        _, rewards, _, infos = env.step(np.zeros((2, 3), np.float32))
    assert np.isfinite(rewards).all() and all(LEARNED_STAGE in info and STAGE_FRAME_KEY not in info for info in infos)
    model = load_model(folder)
    options = {"config": PIXELS}
    demos = load_demos(config.dataset, "valid", "ego", 48, 1, progress_bar=False)
    frames = load_stage_frames(model, [3], options, config.dataset, "valid", 1, progress_bar=False)
    embedding = {"config": EMBEDDING}
    assert load_stage_frames(model, [3], embedding, config.dataset, "valid", 1, progress_bar=False) is None
    with pytest.raises(ValueError, match="reads the 'allo' camera"):
        evaluate(model, demos, [3], tmp_path / "q", False, options, negative_episodes=1)
    report = evaluate(model, demos, [3], tmp_path / "q", False, options, negative_episodes=1, stage_frames=frames)
    assert report["schemes"]["3"]["scorer"]["config"]["stage_evidence"] == "pixels"
    assert set(report["schemes"]["3"]["false_completion_any"]) == {"random", "wrong_order"}


def test_a_stream_pairs_scene_frames_by_stamp_and_drops_a_frame_whose_partner_is_lost(tiny_tcc_run, scene_model):
    config, _ = tiny_tcc_run
    model = load_model(scene_model[0])
    ego, allo = demo_frames(config.dataset, "ego")[0][:5], demo_frames(config.dataset, "allo")[0][:5]
    streams = StreamScorer(RewardScorer(model, 3, config=PIXELS))
    assert streams.stage_camera == "allo"
    streams.submit(0, 1, ego[0])
    streams.submit(0, 2, ego[1])
    assert streams.flush() == []  # stamp 1 waits for its scene frame, and stamp 2 after it
    streams.submit_stage(0, 1, allo[0])
    streams.submit_stage(0, 2, allo[1])
    assert [frame.stamp for frame in streams.flush()] == [1, 2]
    streams.submit(0, 3, ego[2])  # its scene frame never comes
    streams.submit(0, 4, ego[3])
    streams.submit_stage(0, 4, allo[3])  # a newer scene stamp: stamp 3's partner is lost
    scored = streams.flush()
    assert [frame.stamp for frame in scored] == [4]  # 3 dropped, 4 not held back
    expected = RewardScorer(model, 3, config=PIXELS).score(
        ego[[0, 1, 3]], allo[[0, 1, 3]], Steps(np.zeros(3, int), np.arange(3))
    )
    np.testing.assert_allclose(scored[0].total, expected.total[-1], rtol=1e-5)
    streams.submit_stage(0, 5, allo[4])  # its ego frame is late, then the scene stream moves on
    streams.submit_stage(0, 6, allo[4])
    streams.submit(0, 6, ego[4])
    assert [frame.stamp for frame in streams.flush()] == [6]  # the orphan scene frame 5 goes too
    stats = streams.take_stats()
    assert stats["dropped_unpaired"] == 1 and stats["dropped_stage_unpaired"] == 1 and stats["dropped"] == 2
    assert stats["waited_for_stage_frame"] == 3 and stats["stage_wait_p99_ms"] > 0  # stamps 1, 2 and 4: not 6
    assert any("no allo camera frame of stamp 3" in line for _, line in streams.log.take())


def test_the_reward_node_pairs_the_simulators_two_cameras(graph, scene_model):
    graph.start("sim0", *sim_node_args("sim0", "-p", "mode:=realtime"))
    graph.start(
        "reward", *reward_node_args(scene_model[0], "-p", "streams:=[sim0]", "-p", "reward.stage_evidence:=pixels")
    )
    rewards = graph.watch(Reward, "sim0/reward", lambda rewards: len(rewards) >= 8)
    assert len(rewards) >= 8, graph.log("reward")
    stamps = [(r.header.stamp.sec, r.header.stamp.nanosec) for r in rewards]
    assert stamps == sorted(set(stamps)) and all(np.isfinite(r.total) for r in rewards)
    assert "stage from ['sim0/camera/allo/image_raw'] (allo camera)" in graph.log("reward")


def test_a_lost_scene_frame_is_dropped_as_unpaired_and_holds_nothing_back(graph, tiny_tcc_run, scene_model, tmp_path):
    config, _ = tiny_tcc_run
    ego, allo = demo_frames(config.dataset, "ego")[0][:6], demo_frames(config.dataset, "allo")[0][:6]
    np.save(tmp_path / "ego.npy", ego)
    np.save(tmp_path / "allo.npy", allo)
    graph.start(
        "reward",
        *reward_node_args(scene_model[0], "-p", "image_topic:=camera/image_raw", "-p", "reward.stage_evidence:=pixels"),
    )
    camera = subprocess.run(
        [sys.executable, FOREIGN_CAMERA, tmp_path / "ego.npy", tmp_path / "out.json",
         "--scene", tmp_path / "allo.npy", "--withhold", "2"],
        env=graph.env, capture_output=True, text=True, timeout=240,
    )  # fmt: skip
    assert camera.returncode == 0, camera.stdout + camera.stderr + graph.log("reward")
    received = json.loads((tmp_path / "out.json").read_text())
    # every frame but the one whose scene frame was withheld got its reward, each before the next was sent
    assert [r["stamp"] for r in received["rewards"]] == [(i + 1) * PERIOD_NS for i in (0, 1, 3, 4, 5)]
    assert received["stamps"] == [r["stamp"] for r in received["rewards"]]
    assert received["unpaired_total"] == 1
    assert f"no allo camera frame of stamp {3 * PERIOD_NS}" in graph.log("reward")


@pytest.mark.parametrize("order", ["ego first", "scene first", "reset first"])
def test_a_clock_jump_after_a_lone_scene_frame_drops_no_frame_whose_partner_came(tiny_tcc_run, scene_model, order):
    """The old clock's last scene frame, whose ego frame never came, is of no use once the clock
    goes back (stamps jump, or `reset_reward` and a restarted simulator): it is dropped with that
    cause, and every new frame whose scene frame comes is scored (it once cost the next 16)."""
    config, _ = tiny_tcc_run
    ego, allo = (demo_frames(config.dataset, view)[0] for view in ("ego", "allo"))
    streams = StreamScorer(RewardScorer(load_model(scene_model[0]), 3, config=PIXELS))
    for index in (1, 2, 3):
        streams.submit(0, (100 + index) * PERIOD_NS, ego[index])
        streams.submit_stage(0, (100 + index) * PERIOD_NS, allo[index])
        streams.flush()
    streams.submit_stage(0, 104 * PERIOD_NS, allo[4])  # its ego frame is lost, then the clock goes back
    if order == "reset first":
        streams.reset(0)
    scored = []
    for stamp in range(1, 21):
        index = stamp % len(ego)
        if order == "scene first":
            streams.submit_stage(0, stamp * PERIOD_NS, allo[index])
        scored += streams.submit(0, stamp * PERIOD_NS, ego[index])
        scored += streams.flush()  # the node's round wait is over before the scene frame comes
        if order != "scene first":
            streams.submit_stage(0, stamp * PERIOD_NS, allo[index])
        scored += streams.flush()
    assert [frame.stamp for frame in scored] == [stamp * PERIOD_NS for stamp in range(1, 21)]
    assert [frame.episode_frame for frame in scored] == list(range(1, 21))  # a new episode from the jump on
    stats = streams.take_stats()
    assert stats.get("dropped_unpaired", 0) == 0 and stats["dropped_stage_unpaired"] == 1
    lines = [line for _, line in streams.log.take()]
    assert any("allo camera's clock jumped back 12.875 s: dropped 1 allo frame" in line for line in lines), lines
    assert not any("no allo camera frame" in line for line in lines), lines


def test_the_reward_node_scores_every_paired_frame_after_a_clock_jump(graph, tiny_tcc_run, scene_model, tmp_path):
    config, _ = tiny_tcc_run
    ego, allo = (demo_frames(config.dataset, view)[0] for view in ("ego", "allo"))
    order = np.arange(24) % len(ego)
    np.save(tmp_path / "ego.npy", ego[order])
    np.save(tmp_path / "allo.npy", allo[order])
    graph.start(
        "reward",
        *reward_node_args(scene_model[0], "-p", "image_topic:=camera/image_raw", "-p", "reward.stage_evidence:=pixels"),
    )
    camera = subprocess.run(
        [sys.executable, FOREIGN_CAMERA, tmp_path / "ego.npy", tmp_path / "out.json", "--scene", tmp_path / "allo.npy",
         "--jump-back", "4", "--scene-delay", "0.02"],
        env=graph.env, capture_output=True, text=True, timeout=240,
    )  # fmt: skip
    assert camera.returncode == 0, camera.stdout + camera.stderr + graph.log("reward")
    received = json.loads((tmp_path / "out.json").read_text())
    # every frame got its reward, each before the next was sent: 4 before the jump, 20 after it
    expected = [(i + 1) * PERIOD_NS for i in range(4)] + [(i + 1) * PERIOD_NS for i in range(20)]
    assert [r["stamp"] for r in received["rewards"]] == expected
    assert received["unpaired_total"] == 0 and received["stage_unpaired_total"] == 1
    log = graph.log("reward")
    assert "allo camera's clock jumped back" in log and "no allo camera frame" not in log, log


def test_the_scene_head_fits_on_file_labelled_clips_of_its_own_camera(tiny_tcc_run, tmp_path, capsys):
    from inest_reward_node.learning.calibrate import stage_head_episodes, supervision
    from inest_reward_node.learning.clips import random_play, save_clips

    config, run_dir = tiny_tcc_run
    size = config.encoder.image_size
    scene = tmp_path / "scene.npz"
    save_clips(scene, random_play("allo", size, 2), "allo", "two random-play episodes", labelled_by="file")
    head = dataclasses.replace(config.calibration.stage_head, view="allo")
    calibration = CalibrationConfig(
        random_episodes=0,
        wrong_order_episodes=0,
        stage_head=head,
        stage_head_subtasks=(3,),
        stage_head_clips=(str(scene),),
    )
    with_clips = dataclasses.replace(config, calibration=calibration)
    demos = load_demos(config.dataset, "train", "ego", size, 1, progress_bar=False)
    labelled, played = stage_head_episodes(with_clips, demos, [])
    assert len(labelled) == 1 and len(played) == 2 and played[0].frames.shape[1:] == (size, size, 3)
    record = supervision(with_clips, demonstrations=1)
    assert record["negatives"][f"stage-head-clips:{scene}"] == {"episodes": 2, "labelled_by": "file"}
    assert record["labelled_episodes"] == 2 and record["simulator_labelled_episodes"] == 0
    # a clip file of another camera is refused before any work, in one line
    ego = tmp_path / "ego.npz"
    save_clips(ego, random_play("ego", size, 1), "ego", "one random-play episode", labelled_by="file")
    argv = [config.dataset, "--out", str(tmp_path / "refit"), "--recalibrate", str(run_dir / "model")]
    argv += ["--stage-head-view", "allo", "--stage-head-clips", str(ego)]
    assert pretrain.main(argv) == 2
    error = capsys.readouterr().err
    assert "clips of the 'ego' view; the model uses 'allo'" in error and error.count("\n") == 1
    assert not (tmp_path / "refit" / "model").exists()
