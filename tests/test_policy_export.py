"""Validation and test layouts, exported policies and `inest-evaluate`: a committed run is
re-evaluated without retraining and repeats its own final evaluation."""

from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest
from inest_agent_node.evaluate import LAYOUT_SETS, layouts
from inest_agent_node.learners import learner_class
from inest_agent_node.policy_export import export_policy, load_policy
from inest_agent_node.train import Trainer, new_learner, restore_learner
from safetensors.numpy import load_file, save_file
from small_training import small_train_config

from inest_experiments import reevaluate


def test_layout_sets_are_disjoint_and_a_seed_range_is_bounded():
    validation, test = layouts("validation"), layouts("test")
    assert test.first - validation.first >= 1_000_000 and validation.first - LAYOUT_SETS["legacy"] >= 1_000_000
    assert layouts("test", run_seed=2) == test  # the same test layouts for every seed and method
    assert layouts("legacy", run_seed=2).first == 10_000_002  # where runs before the split were evaluated
    bounded = layouts("500:510")
    assert (bounded.first, bounded.size) == (500, 10)
    with pytest.raises(ValueError, match="11 episodes asked of the 10 layouts 500:510"):
        bounded.check(11)
    for bad in ("train", "10:5", "a:b", "7"):
        with pytest.raises(ValueError, match="seed range FIRST:STOP"):
            layouts(bad)


@pytest.mark.parametrize("learner", ["sbx_sac", "sac"])
def test_an_exported_actor_acts_as_the_learner_s_deterministic_policy(learner, tmp_path):
    config = small_train_config(reward="env", learner=learner)
    trainer = Trainer(config, tmp_path / "run", progress_bar=False)
    trainer.train()
    policy = load_policy(tmp_path / "run")  # written at the checkpoint, in policy/
    observations = np.random.default_rng(0).uniform(-1, 1, (32, 24)).astype(np.float32)
    expected = trainer.model.predict(observations, deterministic=True)[0]
    np.testing.assert_allclose(policy.predict(observations), expected, atol=1e-5)
    assert policy.info["observation"] == "robot" and "ordered_progress" not in policy.info["observation_fields"]
    assert policy.config == config and policy.info["steps"] == 200
    loaded = new_learner(learner_class(learner), config, trainer.env)
    restore_learner(loaded, learner, tmp_path / "run")
    export_policy(loaded, config, tmp_path / "again")  # a saved model exports the same actor
    np.testing.assert_allclose(load_policy(tmp_path / "again").predict(observations), expected, atol=1e-5)
    with pytest.raises(ValueError, match="observes 24 values"):
        policy.predict(observations[:, :20])
    many = np.repeat(observations[:4], 2000, axis=0)  # sampled actions spread as the learner's own do
    sampled = policy.sample(many, np.random.default_rng(1)).reshape(4, 2000, 3)
    learners = trainer.model.predict(many, deterministic=False)[0].reshape(4, 2000, 3)
    np.testing.assert_allclose(sampled.mean(1), learners.mean(1), atol=0.05)
    np.testing.assert_allclose(sampled.std(1), learners.std(1), atol=0.05)
    tensors = load_file(str(tmp_path / "run" / "policy" / "actor.safetensors"))
    save_file({k: v for k, v in tensors.items() if not k.startswith("log_std")}, str(tmp_path / "old.safetensors"))
    (tmp_path / "old.safetensors").replace(tmp_path / "run" / "policy" / "actor.safetensors")
    older = load_policy(tmp_path / "run")  # exported before the log std was kept: mean actions only
    np.testing.assert_allclose(older.predict(observations), expected, atol=1e-5)
    with pytest.raises(ValueError, match="without its log std layer"):
        older.sample(observations, np.random.default_rng(0))
    with pytest.raises(ValueError, match="exporting a crossq policy is not supported"):
        export_policy(loaded, small_train_config(reward="env", learner="crossq"), tmp_path / "crossq")


def test_inest_evaluate_repeats_a_run_s_final_evaluation_and_refuses_bad_input(tmp_path, capsys):
    config = small_train_config(reward="env", final_eval_episodes=4, total_steps=400)
    run = tmp_path / "run"
    Trainer(config, run, progress_bar=False).train()
    results = json.loads((run / "results.json").read_text())
    assert results["layouts"]["final_evaluation"] == {"name": "test", "first_seed": LAYOUT_SETS["test"]}
    assert results["layouts"]["learning_curve"]["name"] == "validation" and results["final_validation"]["episodes"] == 4
    assert reevaluate.main([str(run), "--episodes", "4"]) == 0
    again = json.loads((run / "evaluations" / "test-4.json").read_text())
    assert again["evaluation"] == results["final_evaluation"] and again["policy_steps"] == 400
    assert reevaluate.main([str(run / "policy"), "--episodes", "4", "--layouts", "validation"]) == 0
    assert (
        json.loads((run / "evaluations" / "validation-4.json").read_text())["evaluation"] == results["final_validation"]
    )
    assert "run" in capsys.readouterr().out
    assert reevaluate.main([str(run), "--layouts", "training"]) == 2
    assert "layouts must be one of" in capsys.readouterr().err
    assert reevaluate.main([str(tmp_path / "nothing")]) == 2
    assert "no exported policy" in capsys.readouterr().err


def test_the_locked_test_set_is_scored_once_per_run_for_a_release_with_its_commit(tmp_path, capsys):
    run = tmp_path / "run"
    Trainer(small_train_config(reward="env", final_eval_episodes=2), run, progress_bar=False).train()
    repo = tmp_path / "repo"
    (repo / "results").mkdir(parents=True)
    (repo / "notes.txt").write_text("v1\n")
    for command in (
        ["init", "-q"],
        ["add", "notes.txt"],
        ["-c", "user.name=t", "-c", "user.email=t@t", "commit", "-qm", "v1"],
    ):
        subprocess.run(["git", "-C", str(repo), *command], check=True)
    head = subprocess.run(["git", "-C", str(repo), "rev-parse", "HEAD"], capture_output=True, text=True).stdout.strip()
    ledger = repo / "results" / "ledger.json"
    locked = [str(run), "--layouts", "locked", "--episodes", "2", "--ledger", str(ledger)]
    with pytest.raises(ValueError, match="locked test set"):
        layouts("locked")  # nothing else may draw from it: not training, not a seed range
    with pytest.raises(ValueError, match="locked test set"):
        layouts("49999990:50000010")
    with pytest.raises(SystemExit):
        reevaluate.main(locked)  # no release named
    assert "go together" in capsys.readouterr().err
    (repo / "notes.txt").write_text("v2, not committed\n")
    assert reevaluate.main([*locked, "--release", "v1"]) == 2
    assert "commit first" in capsys.readouterr().err and not ledger.exists()
    (repo / "notes.txt").write_text("v1\n")
    assert reevaluate.main([str(run / "policy"), *locked, "--release", "v1"]) == 2  # the same run twice
    assert "named twice" in capsys.readouterr().err and not ledger.exists()
    assert reevaluate.main([*locked, "--release", "v1"]) == 0
    entry = json.loads(ledger.read_text())["entries"][0]
    assert entry["release"] == "v1" and entry["commit"] == head and entry["run"] == run.resolve().as_posix()
    assert entry["evaluation"] == json.loads((run / "evaluations" / "locked-2.json").read_text())["evaluation"]
    capsys.readouterr()
    assert reevaluate.main([*locked, "--release", "v2"]) == 2  # once per run, whatever the release
    assert "scored on the locked test layouts already (release v1" in capsys.readouterr().err
    assert len(json.loads(ledger.read_text())["entries"]) == 1
