"""Model folders: safe round trip, clear mismatch errors, resumable training runs."""

from __future__ import annotations

import dataclasses
import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
from inest_reward_node.learning.data import load_demos
from inest_reward_node.learning.pretrain import STATE_FILE, Pretrainer, dataset_hash, pretrain
from inest_reward_node.runtime.encoders import EncoderConfig
from inest_reward_node.runtime.model import MODEL_FILE, WEIGHTS_FILE, ModelError, load_model
from safetensors import safe_open


def test_model_round_trip_keeps_weights_and_calibration(tiny_tcc_run):
    config, run_dir = tiny_tcc_run
    folder = run_dir / "model"
    model = load_model(folder, view="ego", image_size=48, scheme=3)
    metadata = json.loads((folder / MODEL_FILE).read_text())
    assert metadata["view"] == "ego" and metadata["encoder"]["image_size"] == 48
    assert metadata["dataset"]["sha256"] == dataset_hash(config.dataset)
    assert sorted(metadata["subtasks"]) == ["1", "3", "6"]
    with safe_open(str(folder / WEIGHTS_FILE), framework="pt") as weights:  # plain tensors, no pickle
        assert len(list(weights.keys())) > 10
    trainer = Pretrainer(config, run_dir, resume=True)  # the training state holds the same weights
    demo = load_demos(config.dataset, "valid", "ego", 48, limit=1, progress_bar=False)[0]
    with torch.no_grad():
        from inest_reward_node.runtime.encoders import frames_to_tensor

        expected = trainer.network.eval()(frames_to_tensor(demo.frames)).numpy()
    np.testing.assert_allclose(model.embed(demo.frames), expected, rtol=1e-5, atol=1e-5)
    # frames of another size are resized to the model's input
    assert model.embed(np.zeros((2, 96, 96, 3), np.uint8)).shape == (2, 32)


def test_mismatched_expectations_fail_with_clear_messages(tiny_tcc_run):
    _, run_dir = tiny_tcc_run
    folder = run_dir / "model"
    with pytest.raises(ModelError, match=r"view mismatch: .* 'ego' camera at 48 px, but the caller uses the 'allo'"):
        load_model(folder, view="allo")
    with pytest.raises(ModelError, match=r"input size mismatch: .* asked for 96 px"):
        load_model(folder, image_size=96)
    with pytest.raises(ModelError, match=r"subtask scheme mismatch: .* goals for \[1, 3, 6\] .* asked for 2"):
        load_model(folder, scheme=2)


def test_missing_or_corrupt_model_files_are_reported(tiny_tcc_run, tmp_path):
    _, run_dir = tiny_tcc_run
    with pytest.raises(ModelError, match=r"model\.json is missing"):
        load_model(tmp_path)
    broken = tmp_path / "broken"
    shutil.copytree(run_dir / "model", broken)
    (broken / WEIGHTS_FILE).write_bytes(b"not a safetensors file")
    with pytest.raises(ModelError, match="cannot load weights"):
        load_model(broken)
    document = json.loads((run_dir / "model" / MODEL_FILE).read_text())
    del document["encoder"]
    (broken / MODEL_FILE).write_text(json.dumps(document))
    with pytest.raises(ModelError, match=r"model\.json is not a valid reward model description \(KeyError: 'encoder'"):
        load_model(broken)
    (broken / MODEL_FILE).write_text("{")
    with pytest.raises(ModelError, match="corrupt"):
        load_model(broken)


def test_weights_of_another_architecture_are_one_short_line(tiny_tcc_run, tmp_path):
    config, run_dir = tiny_tcc_run
    other = tmp_path / "other"
    shutil.copytree(run_dir / "model", other)
    document = json.loads((other / MODEL_FILE).read_text())
    document["encoder"]["widths"] = [16, 32, 32, 32]  # the weights were trained with the default widths
    (other / MODEL_FILE).write_text(json.dumps(document))
    command = [Path(sys.executable).parent / "inest-reward-quality", other, config.dataset, "--out", tmp_path / "q"]
    run = subprocess.run(command, capture_output=True, text=True, check=False)
    assert run.returncode == 2 and "Traceback" not in run.stderr, run.stderr
    assert len(run.stderr.strip().splitlines()) == 1 and len(run.stderr) < 400, run.stderr
    assert "weights of another architecture" in run.stderr and "of another shape (first " in run.stderr


def test_typed_metadata_writes_back_the_document_it_was_read_from(tiny_tcc_run):
    _, run_dir = tiny_tcc_run
    document = json.loads((run_dir / "model" / MODEL_FILE).read_text())
    metadata = load_model(run_dir / "model").metadata
    assert metadata.encoder.image_size == 48 and sorted(metadata.subtasks) == [1, 3, 6]
    written = json.loads(json.dumps(metadata.to_dict()))  # tuples become lists, as in the file
    assert written == {key: value for key, value in document.items() if not key.startswith("format")}


def test_interrupted_run_resumes_where_it_stopped(tiny_tcc_run, tmp_path):
    config, _ = tiny_tcc_run
    short = dataclasses.replace(config, iterations=10, checkpoint_every=5, validate_every=5)
    run_dir = tmp_path / "run"
    pretrain(short, run_dir, progress_bar=False)
    first = torch.load(run_dir / STATE_FILE, weights_only=True)
    assert first["iteration"] == 10
    with pytest.raises(FileExistsError, match="--resume"):
        Pretrainer(short, run_dir)
    with pytest.raises(ValueError, match="settings differ from the saved run: learning_rate"):
        Pretrainer(dataclasses.replace(short, iterations=20, learning_rate=0.5), run_dir, resume=True)
    saved = json.loads((run_dir / "config.json").read_text())
    del saved["encoder"]["widths"]  # a run written before the setting existed: it used the default
    (run_dir / "config.json").write_text(json.dumps(saved))
    with pytest.raises(ValueError, match="settings differ from the saved run: encoder"):
        Pretrainer(
            dataclasses.replace(short, encoder=EncoderConfig(image_size=48, widths=(8, 8))), run_dir, resume=True
        )
    longer = dataclasses.replace(short, iterations=15)
    trainer = Pretrainer(longer, run_dir, resume=True)
    assert trainer.iteration == 10
    pretrain(longer, run_dir, resume=True, progress_bar=False)
    state = torch.load(run_dir / STATE_FILE, weights_only=True)
    history = json.loads(state["history"])
    assert state["iteration"] == 15
    assert [step for step, _ in history["train"]] == list(range(1, 16))
    assert load_model(run_dir / "model").metadata.training["iterations"] == 15


def test_resnet18_models_train_save_and_load(tiny_tcc_run, tmp_path):
    config, _ = tiny_tcc_run
    resnet = dataclasses.replace(
        config,
        encoder=dataclasses.replace(config.encoder, kind="resnet18"),
        iterations=2,
        videos_per_batch=2,
        frames_per_video=8,
    )
    pretrain(resnet, tmp_path, progress_bar=False)
    model = load_model(tmp_path / "model", scheme=6)
    assert model.encoder_config.kind == "resnet18"
    assert model.embed(np.zeros((3, 48, 48, 3), np.uint8)).shape == (3, 32)


def test_pretraining_options_for_augmentation_and_the_device(tiny_tcc_run, tmp_path, capsys):
    from inest_reward_node.learning.pretrain import main, parse_args

    dataset = tiny_tcc_run[0].dataset
    config, _ = parse_args([dataset, "--out", "x", "--augment-shift", "8", "--augment-brightness", "0.4"])
    assert (config.augment.max_shift, config.augment.brightness, config.augment.contrast) == (8, 0.4, 0.2)
    assert config.device == "cpu" and "device" not in config.settings_that_matter()  # a resumed run may move
    bad_inputs = (
        (["--device", "tpu"], "unknown device 'tpu'"),
        (["--device", "cuda"], "sees no GPU"),
        (["--augment-shift", "-1"], "max_shift must be >= 0"),
        (["--augment-brightness", "1.5"], "brightness must be in [0, 1)"),
    )
    for flags, message in bad_inputs:
        if "cuda" in flags and torch.cuda.is_available():
            continue
        assert main([dataset, "--out", str(tmp_path / "run"), *flags]) == 2
        error = capsys.readouterr().err
        assert error.count("\n") == 1 and message in error
        assert not (tmp_path / "run").exists()  # refused before a run folder is made
