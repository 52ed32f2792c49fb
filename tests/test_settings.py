"""Settings declared once: the commands' flags come from the config dataclasses (help from the
fields' comments, choices from their types) and no command keeps a long hand-written parser."""

from __future__ import annotations

import argparse
import inspect
from dataclasses import dataclass, field
from typing import Literal

import pytest
from inest_common.settings import CHOICES, add_setting_flags, build_settings, check_choices
from inest_reward_node.learning import pretrain, quality
from inest_reward_node.runtime.config import RewardConfig

from inest_agent_node import train
from inest_agent_node.config import TrainConfig

MAX_PARSER_LINES = 40


@dataclass(frozen=True)
class Inner:
    colour: Literal["red", "blue"] = "red"  # which block
    sizes: tuple[int, ...] = (1, 2)

    def __post_init__(self) -> None:
        check_choices(self)


@dataclass(frozen=True)
class Outer:
    # how many, a comment above
    count: int = 3
    name: str = field(default="a", metadata={CHOICES: lambda: ("a", "b")})
    fast: bool = False
    inner: Inner = field(default_factory=Inner)

    def __post_init__(self) -> None:
        check_choices(self)
        if self.count < 0:
            raise ValueError("count must be >= 0")


def parse(argv: list[str], **options) -> Outer:
    parser = argparse.ArgumentParser()
    flags = add_setting_flags(parser, Outer, **options)
    return build_settings(Outer, flags.overrides(parser.parse_args(argv)))


def test_flags_come_from_the_fields():
    assert parse([]) == Outer()
    given = parse(["--count", "5", "--name", "b", "--fast", "--inner-colour", "blue", "--inner-sizes", "4,5", "6"])
    assert given == Outer(count=5, name="b", fast=True, inner=Inner(colour="blue", sizes=(4, 5, 6)))
    assert parse(["--colour", "blue"], prefixes={"inner": ""}).inner.colour == "blue"
    assert parse(["--block", "blue"], flags={"inner.colour": "block"}).inner.colour == "blue"
    with pytest.raises(SystemExit):
        parse(["--inner-colour", "green"])  # argparse knows the Literal's choices


def test_help_comes_from_the_comments():
    parser = argparse.ArgumentParser()
    add_setting_flags(parser, Outer)
    text = " ".join(parser.format_help().split())
    assert "how many, a comment above (default: 3)" in text
    assert "which block (default: red)" in text
    assert "{a,b}" in text  # a registry's choices, read when the flags are made


def test_choices_and_unknown_settings_are_one_line_errors():
    with pytest.raises(ValueError, match=r"unknown name 'c'; expected one of \('a', 'b'\)"):
        Outer(name="c")
    with pytest.raises(ValueError, match=r"unknown setting\(s\) \['cuont'\] \(did you mean count\?\)"):
        build_settings(Outer, {"cuont": 1})
    with pytest.raises(ValueError, match=r"unknown colour 'green'"):
        build_settings(Outer, {"inner": {"colour": "green"}})
    with pytest.raises(ValueError, match="wrong type or is missing"):
        build_settings(Outer, {"count": "3"})


def test_the_commands_flags_reach_their_configs():
    config, _ = train.parse_args(
        [
            "--out",
            "o",
            "--model",
            "m",
            "--intrinsic-weight",
            "1",
            "--gradient-steps",
            "1",
            "--label-at",
            "5",
            "--refit-demos",
            "d",
        ]
    )
    assert config.intrinsic.weight == 1 and config.intrinsic.boosted_weight == 2  # the thesis's doubling
    assert config.sac.gradient_steps == 1 and config.label_at == (5,)
    config, _ = train.parse_args(["--out", "o", "--reward", "env"])
    assert config.intrinsic.mode == "none" and config == TrainConfig.from_dict({"reward": "env"})
    config, _ = pretrain.parse_args(
        ["d", "--out", "o", "--threshold-percentile", "5", "--no-augment", "--widths", "8,16"]
    )
    assert config.calibration.percentile == 5 and not config.augment.enabled and config.encoder.widths == (8, 16)
    assert quality.reward_config({"tracker": "threshold"}) == RewardConfig(tracker="threshold")


@pytest.mark.parametrize("function", [train.parse_args, pretrain.parse_args, quality.main])
def test_no_hand_written_parser_is_long(function):
    lines = inspect.getsource(function).splitlines()
    until_parsed = next(index for index, line in enumerate(lines) if "parser.parse_args(" in line) + 1
    assert until_parsed <= MAX_PARSER_LINES
