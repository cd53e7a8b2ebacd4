"""The shared preparation step: windows, the design check, and one preparation serving identify and fit."""

import numpy as np
import pytest

from scioc.pipelines.identify import identify_prepared, identify_study, identify_to_dir
from scioc.pipelines.io import InputDataError, validate_table
from scioc.pipelines.prepare import IdentifySettings, check_design, prepare_study
from tests.pipelines.test_io import small_table


@pytest.fixture(scope="module")
def study():
    return validate_table(small_table(K=400), "<small>")


def test_prepare_study_cuts_every_segment_in_file_order(study):
    settings = IdentifySettings(window_start=1.0, window_seconds=2.0, preview=0.5, adequacy_boot=0)
    prepared = prepare_study(study, settings)
    assert prepared.settings == settings and prepared.seconds >= 0
    assert prepared.subjects == [s.subject for s in study.segments]
    assert prepared.labels == [f"{s.subject}/{s.condition}" for s in study.segments]
    assert all(p.segment.K == 200 and p.segment.preview == 50 for p in prepared.segments)


def test_identify_from_a_prepared_study_is_identify_from_the_file(study):
    settings = IdentifySettings(window_start=1.0, window_seconds=2.0, adequacy_boot=0)
    a = identify_study(study, settings, show_progress=False)
    b = identify_prepared(prepare_study(study, settings))
    assert a.estimates.drop(columns=["message"]).equals(b.estimates.drop(columns=["message"]))


def test_a_study_prepared_with_other_settings_is_refused(study, tmp_path):
    prepared = prepare_study(study, IdentifySettings(window_start=1.0, window_seconds=2.0, adequacy_boot=0))
    with pytest.raises(ValueError, match="other settings"):
        identify_to_dir("unused.parquet", tmp_path / "out", IdentifySettings(adequacy_boot=0), prepared=prepared)


def test_the_design_check_names_the_file_and_the_missing_condition():
    with pytest.raises(InputDataError, match=r"^study.parquet: .*S2.*SC"):
        check_design("study.parquet", ["S1", "S1", "S2"], ["MC", "SC", "MC"])
    check_design("study.parquet", np.array(["S1", "S1"]), ["MC", "SC"])  # complete: no error
