"""A new study is its module and one registry entry: a toy study (coin flips), registered from
this test alone, runs through ``himit run NAME --help``, ``himit run NAME``, ``--resume`` and
``himit plot`` with no other file changed; and ``himit plot`` finds every registered study
from the run directory's ``config.json``."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import pytest
import torch

from himit_torch.cli import main
from himit_torch.runs import studies
from himit_torch.runs.study import RunConfig, StudyEntry, run_each, run_study
from himit_torch.validation import setting


@dataclass
class CoinConfig(RunConfig):
    """A toy study's configuration: ``seeds`` runs of ``flips`` coin flips."""

    name: str = RunConfig.shared("name", "coins")
    seeds: int = RunConfig.shared("seeds", 3)
    first_seed: int = RunConfig.shared("first_seed", 0)
    flips: int = setting(20, ge=1, doc="Coin flips per seed.")

    def __post_init__(self):
        self.check_run_settings()


#: The seeds each call of the toy's run ran (what --resume must not rerun).
RAN: list[int] = []


def _heads(run_dir: Path) -> dict[int, int]:
    return {
        int(p.stem.removeprefix("seed")): json.loads(p.read_text())["heads"]
        for p in sorted((run_dir / "records").glob("seed*.json"))
    }


def _write_page(run_dir: Path) -> None:
    heads = _heads(run_dir)
    rows = [f"| {seed} | {n} |" for seed, n in heads.items()]
    (run_dir / "results.md").write_text("\n".join(["| seed | heads |", *rows]) + "\n")


class CoinStudy:
    config_class: ClassVar[type] = CoinConfig
    folders: ClassVar[tuple[str, ...]] = ("records",)
    files: ClassVar[tuple[str, ...]] = ("config.json", "results.md")

    def run(self, config: CoinConfig, run_dir: Path, resume: bool, progress: bool) -> None:
        (run_dir / "records").mkdir(exist_ok=True)
        for seed in config.seed_list:
            path = run_dir / "records" / f"seed{seed}.json"
            if resume and path.exists():
                continue
            RAN.append(seed)
            flips = torch.rand(config.flips, generator=torch.Generator().manual_seed(seed))
            path.write_text(json.dumps({"heads": int((flips < 0.5).sum())}))

    def report(self, config: CoinConfig, run_dir: Path, results: None) -> None:
        _write_page(run_dir)


def run_coins(config, run_dir, resume=False, force=False, progress=True):
    return run_study(CoinStudy(), config, run_dir, resume=resume, force=force, progress=progress)


COINS = StudyEntry(
    "coins",
    "a toy study: coin flips per seed",
    CoinConfig,
    configs=lambda: (CoinConfig(),),
    run=run_each(run_coins, resume=True),
    describe=lambda config, run_dir: f"{config.name}: {config.seeds} seeds → {run_dir}",
    redraw=_write_page,
    run_flags=("resume",),
)


@pytest.fixture
def coins(monkeypatch):
    monkeypatch.setitem(studies.STUDIES, "coins", COINS)
    RAN.clear()
    return COINS


def test_a_registered_toy_study_runs_resumes_and_redraws_through_the_cli(coins, tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["run", "coins", "--help"])
    assert exc.value.code == 0
    help_text = capsys.readouterr().out
    assert "--flips" in help_text and "Coin flips per seed" in help_text and "--resume" in help_text
    assert "--sizes" not in help_text  # another study's setting

    argv = ["run", "coins", "--logdir", str(tmp_path), "--quiet", "--flips", "50"]
    assert main(argv) == 0
    run_dir = tmp_path / "coins"
    assert "coins: 3 seeds" in capsys.readouterr().out
    assert RAN == [0, 1, 2]
    assert json.loads((run_dir / "config.json").read_text())["flips"] == 50
    page = (run_dir / "results.md").read_text()
    heads = _heads(run_dir)
    assert sorted(heads) == [0, 1, 2] and all(0 <= n <= 50 for n in heads.values())

    # An interrupted run: seed 2's record lost; --resume reruns it alone, the same heads
    (run_dir / "records" / "seed2.json").unlink()
    RAN.clear()
    assert main([*argv, "--resume"]) == 0
    assert RAN == [2] and _heads(run_dir) == heads
    # ...and a resume with other settings is refused in one line
    with pytest.raises(SystemExit) as exc:
        main(["run", "coins", "--logdir", str(tmp_path), "--quiet", "--flips", "9", "--resume"])
    assert exc.value.code == 2 and "different configuration" in capsys.readouterr().err

    # himit plot finds the study from config.json and redraws the same page
    (run_dir / "results.md").write_text("stale")
    assert main(["plot", str(run_dir)]) == 0
    assert (run_dir / "results.md").read_text() == page


def test_himit_plot_finds_each_study_from_its_config(coins, tmp_path):
    for name, config in [
        ("coins", CoinConfig()),
        ("exp1", studies.STUDIES["exp2"].configs()[0]),
        ("gymnasium", studies.STUDIES["gymnasium"].configs()[0]),
        ("discovery", studies.STUDIES["discovery"].configs()[0]),
        ("puzzlebox", studies.STUDIES["puzzlebox"].configs()[0]),
    ]:
        run_dir = tmp_path / name
        run_dir.mkdir()
        (run_dir / "config.json").write_text(config.to_json())
        assert studies.study_of_run_dir(run_dir).name == name


def test_an_unknown_configuration_is_refused_naming_the_file(tmp_path, capsys):
    (tmp_path / "config.json").write_text(json.dumps({"name": "x", "colour": "red"}))
    with pytest.raises(SystemExit) as exc:
        main(["plot", str(tmp_path)])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and "no study's configuration" in err and "config.json" in err


def test_a_name_is_registered_once():
    with pytest.raises(ValueError, match="already registered"):
        studies.register(studies.STUDIES["exp1"])


def test_with_settings_puts_the_preset_first_and_the_learner_settings_beside_it():
    from dataclasses import replace

    from himit_torch.learner.presets import apply_preset
    from himit_torch.runs.config import ExperimentConfig

    base = ExperimentConfig()
    built = base.with_settings({"preset": "paper", "seeds": 3}, {"mentor_trial": True})
    expected_learner = replace(apply_preset(base.learner, "paper"), mentor_trial=True)
    assert (built.preset, built.seeds, built.learner) == ("paper", 3, expected_learner)
    # a None preset records no preset and leaves the learner as it is
    cleared = built.with_settings({"preset": None})
    assert cleared.preset is None and cleared.learner == built.learner
    with pytest.raises(ValueError, match="unknown preset"):
        base.with_settings({"preset": "no-such-preset"})
