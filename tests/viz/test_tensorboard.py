"""TensorBoard logs: one history per run folder (refused, overwritten or resumed on purpose),
scalars and maps with descriptions, hyperparameters that group seeds — read back with
TensorBoard's own EventAccumulator."""

import pytest
import torch

from himit_torch.viz.tensorboard import SCALAR_DESCRIPTIONS, TensorBoardLogger

EventAccumulator = pytest.importorskip(
    "tensorboard.backend.event_processing.event_accumulator"
).EventAccumulator


def read(folder):
    acc = EventAccumulator(str(folder), size_guidance={"images": 0, "scalars": 0})
    acc.Reload()
    return acc


def log_goals(logger: TensorBoardLogger, steps, value: float) -> None:
    for step in steps:
        logger.scalar(0, "charts/goals_in_window", value, step)
    logger.close()


def test_a_second_run_into_a_used_folder_is_refused(tmp_path):
    log_goals(TensorBoardLogger(tmp_path, ["run"]), [5000, 10000], 1.0)
    with pytest.raises(FileExistsError, match="would mix its curves"):
        TensorBoardLogger(tmp_path, ["run"])
    # Nothing was written by the refused attempt: still only the first run's history.
    assert [e.step for e in read(tmp_path / "run").Scalars("charts/goals_in_window")] == [
        5000,
        10000,
    ]


def test_overwrite_starts_a_fresh_history(tmp_path):
    # The bug this guards against: a re-run with another budget appended 500…2000 after 5000…100000.
    log_goals(TensorBoardLogger(tmp_path, ["run"]), [5000, 10000], 1.0)
    log_goals(TensorBoardLogger(tmp_path, ["run"], overwrite=True), [500, 1000], 2.0)
    events = read(tmp_path / "run").Scalars("charts/goals_in_window")
    assert [(e.step, e.value) for e in events] == [(500, 2.0), (1000, 2.0)]


def test_resume_replaces_what_was_logged_after_the_checkpoint(tmp_path):
    log_goals(TensorBoardLogger(tmp_path, ["run"]), [1000, 2000, 3000], 1.0)
    # Checkpoint at 2000: the killed process's 3000 is purged, the resumed one logs it again.
    log_goals(TensorBoardLogger(tmp_path, ["run"], resume_step=2000), [3000, 4000], 2.0)
    events = read(tmp_path / "run").Scalars("charts/goals_in_window")
    assert [(e.step, e.value) for e in events] == [
        (1000, 1.0),
        (2000, 1.0),
        (3000, 2.0),
        (4000, 2.0),
    ]


def test_a_resumed_runs_event_file_is_read_after_the_files_before_it(tmp_path):
    """TensorBoard reads a folder's files in name order; a file of this second whose counter
    sorts after the new one's as text ("99" after "1") would be read last, and its events at
    the purged steps would come back."""
    import time

    log_goals(TensorBoardLogger(tmp_path, ["run"]), [1000, 2000, 3000], 1.0)
    (old,) = (tmp_path / "run").glob("events.out.tfevents.*")
    parts = old.name.split(".")
    parts[3], parts[-1] = str(int(time.time())), "99"
    old.rename(old.with_name(".".join(parts)))
    log_goals(TensorBoardLogger(tmp_path, ["run"], resume_step=2000), [3000, 4000], 2.0)
    files = sorted(p.name for p in (tmp_path / "run").glob("events.out.tfevents.*"))
    assert files[0] == ".".join(parts)
    events = read(tmp_path / "run").Scalars("charts/goals_in_window")
    assert [(e.step, e.value) for e in events][-2:] == [(3000, 2.0), (4000, 2.0)]


def test_scalars_carry_their_descriptions(tmp_path):
    logger = TensorBoardLogger(tmp_path, ["run"])
    logger.scalar(0, "planner/backups", 10, 1)
    logger.scalar(0, "planner/backups", 20, 2)
    logger.close()
    acc = read(tmp_path / "run")
    description = acc.SummaryMetadata("planner/backups").summary_description
    assert description == SCALAR_DESCRIPTIONS["planner/backups"] and "cumulative" in description
    assert [e.value for e in acc.Scalars("planner/backups")] == [10, 20]


def test_the_seed_is_refused_as_a_hyperparameter(tmp_path):
    logger = TensorBoardLogger(tmp_path, ["a"])
    with pytest.raises(ValueError, match="seed"):
        logger.hparams([{"agent": "imitation", "seed": 0}], [{"hparam/total_goals": 1.0}], 10)
    logger.close()


def test_every_description_names_whether_a_count_is_cumulative():
    # planner/ and charts/ counts are cumulative or per window; a reader must not have to guess.
    for tag in (
        "charts/goals_in_window",
        "charts/goals_total",
        "charts/episodes",
        "planner/backups",
        "planner/decisions",
        "charts/steps_per_episode",
    ):
        assert "cumulative" in SCALAR_DESCRIPTIONS[tag] or "per window" in SCALAR_DESCRIPTIONS[tag]


def test_maps_need_the_world(tmp_path):
    logger = TensorBoardLogger(tmp_path, ["a"])
    with pytest.raises(ValueError, match="needs the world"):
        logger.maps(object(), [0], 0, torch.zeros(4))
    logger.close()


def test_an_image_is_encoded_with_the_pixels_of_torchs_make_image():
    """The logger's own PNG encoding (a faster zlib level) keeps make_image's pixels and sizes."""
    import io

    import numpy as np
    from PIL import Image
    from torch.utils.tensorboard.summary import make_image

    from himit_torch.viz.tensorboard import _png

    rng = np.random.default_rng(0)
    rgb = rng.integers(0, 256, size=(37, 53, 3), dtype=np.uint8)
    rgb[:10] = 255  # (a flat band, as a map's background)
    ours, torchs = _png(rgb), make_image(rgb)
    assert (ours.height, ours.width, ours.colorspace) == (torchs.height, torchs.width, 3)

    def pixels(proto) -> np.ndarray:
        return np.asarray(Image.open(io.BytesIO(proto.encoded_image_string)))

    np.testing.assert_array_equal(pixels(ours), pixels(torchs))
    np.testing.assert_array_equal(pixels(ours), rgb)
