"""Fixtures shared by the tests of pipelines/: a small simulated study, identified and fitted once."""

import pytest

from scioc.pipelines.fit import fit_to_dir
from scioc.pipelines.identify import identify_to_dir
from scioc.pipelines.io import load_study
from scioc.pipelines.prepare import prepare_study
from scioc.pipelines.simulate import simulate_to_dir

#: A fit small enough for the test suite: the samplers are not meant to converge here
#: (the numbers are checked for consistency, not for quality).
SMALL = {"seed": 3, "chains": 2, "draws": 100, "tune": 200}
N_SUBJECTS = 6


def _no_reconstruction(*args, **kwargs):
    raise AssertionError("the study was reconstructed a second time")


@pytest.fixture(scope="session")
def small_fit(tmp_path_factory):
    """6 simulated subjects in the layout of ``scioc run``: reconstructed once, identified and fitted from that."""
    root = tmp_path_factory.mktemp("fit") / "study"
    sim = simulate_to_dir(root / "data", n_subjects=N_SUBJECTS, seed=11)
    prepared = prepare_study(load_study(sim["study"]))
    identify_to_dir(sim["study"], root / "identify", show_progress=False, prepared=prepared)
    with pytest.MonkeyPatch.context() as mp:  # the fit takes the prepared study and reconstructs nothing
        mp.setattr("scioc.pipelines.prepare.reconstruct", _no_reconstruction)
        paths = fit_to_dir(sim["study"], root / "fit", prepared=prepared, **SMALL)
    return root, sim, paths
