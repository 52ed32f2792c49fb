"""`inest-model-card MODEL --suite-score FILE [--quality REPORT] [--out CARD.md]`: what a reward
model is and what it pays for wrongly, on one page beside its weights.

Why: a person choosing a reward for a robot asks what it was fitted on (demonstrations,
labelled episodes and who labelled them, cameras) and whether it pays for a block never placed,
before training a policy on it. The card reads the model's own record (model.json), an
`inest-exploit-suite` result (claims on trained policies' rollouts beside random and
wrong-order play) and, if given, an `inest-reward-quality` report (misses on demonstrations).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from inest_common.files import sha256_of, write_atomic
from inest_common.settings import OneLineParser

from ..runtime.config import RewardConfig
from ..runtime.model import MODEL_FILE, ModelError, load_model, model_folder
from .calibrate import describe_supervision, recorded_supervision
from .quality import subtask_name

CARD_FILE = "CARD.md"


def _percent(value: float | None) -> str:
    return "-" if value is None else f"{100 * value:.1f} %"


def reward_settings(score: dict[str, Any]) -> str:
    """The reward settings the suite was scored with, where they differ from RewardConfig's defaults."""
    defaults = vars(RewardConfig())
    config = score.get("scorer_options", {}).get("config", {})
    changed = [f"{key}={value}" for key, value in config.items() if defaults.get(key) != value]
    return ", ".join(changed) or "the default reward settings"


def read_json(path: Path, what: str) -> dict[str, Any]:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError) as error:
        raise ModelError(f"{path}: not {what} ({error})") from None


def claims_table(score: dict[str, Any], quality: dict[str, Any] | None) -> list[str]:
    """Per subtask: the suite's unplaced claims, early claims and misses, play's false completions,
    and the demonstrations' misses when a quality report is given."""
    lines = [
        "| subtask | unplaced claims | early claims | misses (rollouts) | false: random play | false: wrong order |"
        + (" misses (demonstrations) |" if quality else ""),
        "|---|---|---|---|---|---|" + ("---|" if quality else ""),
    ]
    for scheme, row in score["schemes"].items():
        play = score.get("play", {}).get("false_completion_rate", {}).get(scheme, {})
        demos = (quality or {}).get("schemes", {}).get(scheme, {}).get("per_subtask", [])
        for sub in row["per_subtask"]:
            k = sub["subtask"]
            cells = [_percent(sub[key]) for key in ("unplaced_claim_rate", "early_claim_rate", "miss_rate")]
            cells += [_percent(play[kind][k]) if kind in play else "-" for kind in ("random", "wrong_order")]
            if quality:
                cells.append(_percent(demos[k]["miss_rate"]) if k < len(demos) else "-")
            lines.append(f"| {k + 1} {subtask_name(int(scheme), k)} | " + " | ".join(cells) + " |")
    return lines


def card(model_dir: str, score_path: Path, quality_path: Path | None) -> str:
    model = load_model(model_dir)
    score = read_json(score_path, "an inest-exploit-suite result")
    quality = read_json(quality_path, "an inest-reward-quality report") if quality_path else None
    if "schemes" not in score or "part" not in score:
        raise ModelError(f"{score_path}: not an inest-exploit-suite result (no part or schemes)")
    same = (
        score["model_sha256"] == sha256_of(model_folder(model_dir) / MODEL_FILE)
        if "model_sha256" in score
        else Path(score.get("model", "")).resolve() == Path(model_dir).resolve()  # results written before the hash
    )
    if not same:
        raise ModelError(f"{score_path} scores {score.get('model')}, not {model_dir}")
    metadata = model.metadata
    lines = [
        f"# Reward model `{model_dir}`",
        "",
        f"- method {metadata.method}, encoder {metadata.encoder.kind} at {metadata.encoder.image_size} px, "
        f"subtask schemes {sorted(metadata.subtasks)}",
        f"- {describe_supervision(recorded_supervision(metadata))}",
        f"- scored with: {reward_settings(score)}",
        "",
        f"## Claims on the exploit suite, {score['part']} part",
        "",
        f"{score['episodes']} rollouts of {score['policies']} trained policies ({score_path}); an unplaced claim "
        "marks a block done that the episode never places, an early one marks it before it is placed; "
        "misses among the rollouts that placed it.",
        "",
    ]
    for scheme, row in score["schemes"].items():
        unplaced = _percent(row["unplaced_claim_any"])
        lines.append(f"{scheme} subtasks: an unplaced claim of any subtask in {unplaced} of them.")
    played = score.get("play", {}).get("episodes")
    lines += ["", *claims_table(score, quality), ""]
    if played:
        one = 100 / played
        lines += [f"False completions on {played} random and {played} wrong-order episodes (one is {one:.1f} %).", ""]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = OneLineParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("model", help="model folder")
    parser.add_argument("--suite-score", type=Path, required=True, help="inest-exploit-suite --out FILE of this model")
    parser.add_argument("--quality", type=Path, help="inest-reward-quality's report.json of this model")
    parser.add_argument("--out", type=Path, help=f"where to write the card (default MODEL/{CARD_FILE})")
    parser.add_argument("--overwrite", action="store_true", help="replace a card that is already there")
    args = parser.parse_args(argv)
    out = args.out or Path(args.model) / CARD_FILE
    if out.exists() and not args.overwrite:
        print(f"inest-model-card: {out} exists (--overwrite replaces it)", file=sys.stderr)
        return 2
    try:
        text = card(args.model, args.suite_score, args.quality)
        write_atomic(out, lambda path: path.write_text(text))
    except (ModelError, OSError) as error:
        print(f"inest-model-card: {error}", file=sys.stderr)
        return 2
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
