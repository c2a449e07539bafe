"""A small paper-style run that records what its learner was shown: the demonstrations each seed's
learner watched, captured as ``run_experiment`` hands them to ``watch_demonstrations``."""

from himit_torch.runs import experiment as experiment_module
from himit_torch.runs.config import ExperimentConfig, load_config
from himit_torch.runs.experiment import run_experiment


def watched_run(tmp_path, monkeypatch, name: str = "part", **changes):
    """Run one seed of an imitator on a 16×16 world (1,000 steps, 3 mentor episodes) with the
    config ``changes``; returns ``(config, demonstrations seed 0's learner watched)``, after
    checking the run recorded its config."""
    seen = {}
    real_watch = experiment_module.watch_demonstrations

    def watch(learner, demos, mentor=0):
        seen.update(demos)
        real_watch(learner, demos, mentor)

    monkeypatch.setattr(experiment_module, "watch_demonstrations", watch)
    config = ExperimentConfig(name=name, sizes=(16,), room_size=4, seeds=1, steps=1000,
                              window=1000, checkpoint_every=1000, mentor_episodes=3,
                              agents=("imitation",), **changes)  # fmt: skip
    run_experiment(config, tmp_path / "run", progress=False, workers=1)
    assert load_config(tmp_path / "run" / "config.json") == config
    return config, seen[0]
